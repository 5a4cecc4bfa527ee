// stylerf adain --content C --style S [--alpha A] [--size N] -o out.png [--device D] [--timing]
// 2D AdaIN style transfer with the pretrained VGG-19 encoder and decoder (set up with
// `bash scripts/fetch_weights.sh`).
#include <boost/program_options.hpp>
#include <cctype>
#include <filesystem>
#include <chrono>
#include <iostream>

#include "examples/stylerf/commands.hpp"
#include "examples/stylerf/help.hpp"
#include "host/runtime.hpp"
#include "lib/io/image.hpp"
#include "lib/nn/weights.hpp"
#include "lib/style/adain.hpp"

namespace po = boost::program_options;

namespace {

using stylerf::cli::seconds_since;

int run_adain(int argc, char** argv) {
  std::string content, style, output, device;
  float alpha = 1.0f;
  int size = 512;
  bool timing = false;
  po::options_description desc("stylerf adain --content C --style S -o out.png [options]");
  desc.add_options()("help,h", "show this help")("content,c", po::value(&content), "content image (PNG/JPEG)")(
      "style,s", po::value(&style), "style image (PNG/JPEG)")("output,o", po::value(&output), "output image (.png or .jpg)")(
      "alpha", stylerf::cli::value_shown(&alpha), "stylisation strength in [0,1] (0: reconstruct the content)")(
      "size", po::value(&size)->default_value(512), "longer image side in pixels (sides rounded to multiples of 8)")(
      "device", po::value(&device), stylerf::cli::kDeviceHelp)(
      "timing", po::bool_switch(&timing), "print per-kernel times at the end");
  stylerf::cli::apply_renamed_flags("adain", argc, argv, {{"--profile", "--timing"}});
  po::variables_map vm;
  po::store(po::parse_command_line(argc, argv, desc), vm);
  po::notify(vm);
  if (vm.count("help")) {
    stylerf::cli::print_help(std::cout, "adain", desc,
                             "Weights: " + stylerf::nn::weights_dir() + " (set up with `" +
                                 stylerf::nn::kFetchWeightsCommand + "`)");
    return 0;
  }
  if (content.empty() || style.empty() || output.empty()) {
    std::cerr << "stylerf adain: --content, --style and -o are required\n" << desc;
    return 2;
  }
  if (!(alpha >= 0.0f && alpha <= 1.0f)) throw std::runtime_error("--alpha must be in [0, 1]");
  if (size < stylerf::style::kAdainMinSide || size > stylerf::style::kAdainMaxSide)
    throw std::runtime_error("--size must be in [" + std::to_string(stylerf::style::kAdainMinSide) + ", " +
                             std::to_string(stylerf::style::kAdainMaxSide) + "] (got " + std::to_string(size) + ")");
  {  // the output's type before any work: .png or .jpg
    std::string ext = std::filesystem::path(output).extension().string();
    for (char& ch : ext) ch = char(std::tolower(static_cast<unsigned char>(ch)));
    if (ext != ".png" && ext != ".jpg" && ext != ".jpeg")
      throw std::runtime_error("-o " + output + ": unknown image type '" + ext + "' (use .png or .jpg)");
  }

  stylerf::cli::init_runtime(device, timing);
  // Images first: a wrong path is reported before the weights (80 MB) are read.
  auto t1 = std::chrono::steady_clock::now();
  stylerf::io::Image c = stylerf::style::load_image_for_adain(content, size);
  stylerf::io::Image s = stylerf::style::load_image_for_adain(style, size);
  double t_images = seconds_since(t1);

  auto t0 = std::chrono::steady_clock::now();
  auto model = stylerf::style::AdainModel::load_default();
  double t_load = seconds_since(t0);

  auto t2 = std::chrono::steady_clock::now();
  stylerf::io::Image out = stylerf::io::from_tensor(
      stylerf::style::adain_stylize(model, stylerf::io::to_tensor(c), stylerf::io::to_tensor(s), alpha));
  double t_run = seconds_since(t2);  // from_tensor reads back, so the device work is finished here
  for (float& v : out.data) v = std::min(1.0f, std::max(0.0f, v));
  stylerf::io::save_image(output, out);

  std::cout << "wrote " << output << " (" << out.width << "x" << out.height << ", style " << s.width << "x" << s.height
            << ", alpha " << alpha << ")\n"
            << "time: weights " << t_load << " s, images " << t_images << " s, stylise " << t_run << " s\n";
  if (timing) std::cout << stylerf::host::Runtime::instance().timing_report();
  return 0;
}

stylerf::cli::Register reg("adain", run_adain);

}  // namespace
