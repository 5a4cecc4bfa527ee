// stylerf demo-images -o DIR [--size N] [--num-styles N]: writes content.png (a ray-traced scene) and style.png (a painterly
// pattern), both made by stylerf itself, so the demo needs nothing downloaded besides the weights.
#include <boost/program_options.hpp>
#include <filesystem>
#include <iostream>

#include "examples/stylerf/commands.hpp"
#include "examples/stylerf/help.hpp"
#include "lib/demo/procedural_images.hpp"
#include "lib/io/image.hpp"

namespace po = boost::program_options;

namespace {

stylerf::io::Image to_io(const stylerf::demo::RgbImage& src) {
  stylerf::io::Image img;
  img.width = src.width;
  img.height = src.height;
  img.data = src.data;  // both planar [3,H,W]
  return img;
}

int run_demo_images(int argc, char** argv) {
  std::string out_dir;
  int size = 256, styles = 0;
  po::options_description desc("stylerf demo-images -o DIR [options]");
  desc.add_options()("help,h", "show this help")("output,o", po::value(&out_dir), "output folder")(
      "size", po::value(&size)->default_value(256), "image side in pixels")(
      "num-styles", po::value(&styles)->default_value(0), "also write N style images to DIR/styles, each its own palette and texture (style training)");
  stylerf::cli::apply_renamed_flags("demo-images", argc, argv, {{"--out", "--output"}, {"--styles", "--num-styles"}});
  po::variables_map vm;
  po::store(po::parse_command_line(argc, argv, desc), vm);
  po::notify(vm);
  if (vm.count("help") || out_dir.empty()) {
    stylerf::cli::print_help(std::cout, "demo-images", desc);
    return vm.count("help") ? 0 : 2;
  }
  if (size < 16 || size > 4096) throw std::runtime_error("--size must be in [16, 4096]");
  stylerf::io::save_png(out_dir + "/content.png", to_io(stylerf::demo::render_content_image(size, size)));
  stylerf::io::save_png(out_dir + "/style.png", to_io(stylerf::demo::make_style_image(size, size)));
  std::cout << "wrote " << out_dir << "/content.png and " << out_dir << "/style.png (" << size << "x" << size << ")\n";
  if (styles < 0 || styles > 64) throw std::runtime_error("--num-styles must be in [0, 64]");
  if (styles > 0) {
    std::filesystem::create_directories(out_dir + "/styles");
    for (int v = 0; v < styles; ++v)
      stylerf::io::save_png(out_dir + "/styles/style_" + std::to_string(v) + ".png",
                            to_io(stylerf::demo::make_varied_style_image(size, size, v)));
    std::cout << "wrote " << styles << " style images to " << out_dir << "/styles\n";
  }
  return 0;
}

stylerf::cli::Register reg("demo-images", run_demo_images);
}  // namespace
