// stylerf contact-sheet [--contents a,b,c] [--styles w,x,y,z] -o sheet.png [--size N] [--alpha A]
// A grid of 2D AdaIN results: the first row shows the styles, the first column the contents, each other
// cell the content in that style. Defaults use the shared data set ($STYLERF_DATA, else ../shared/data beside the working folder).
#include <boost/algorithm/string.hpp>
#include <boost/program_options.hpp>
#include <chrono>
#include <filesystem>
#include <iostream>

#include "examples/stylerf/commands.hpp"
#include "examples/stylerf/help.hpp"
#include "host/error.hpp"
#include "lib/io/image.hpp"
#include "lib/style/adain.hpp"

namespace po = boost::program_options;
namespace fs = std::filesystem;
using stylerf::io::Image;

namespace {

std::string data_dir() {
  const char* d = std::getenv("STYLERF_DATA");
  return d && *d ? d : "../shared/data";
}

// The first image file of a folder in name order (LLFF folders: the first view).
std::string first_image(const std::string& dir) {
  std::vector<std::string> files;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    std::string ext = boost::algorithm::to_lower_copy(e.path().extension().string());
    if (ext == ".png" || ext == ".jpg" || ext == ".jpeg") files.push_back(e.path().string());
  }
  if (files.empty()) throw stylerf::host::Error("no images in " + dir + " (set STYLERF_DATA or pass --contents)");
  return *std::min_element(files.begin(), files.end());
}

std::vector<std::string> split_list(const std::string& s) {
  std::vector<std::string> parts;
  boost::algorithm::split(parts, s, boost::is_any_of(","));
  parts.erase(std::remove(parts.begin(), parts.end(), ""), parts.end());
  return parts;
}

// Copies img centred into the cell at (row, col) of the sheet.
void paste(Image& sheet, const Image& img, int row, int col, int cell, int gap) {
  const int x0 = gap + col * (cell + gap) + (cell - img.width) / 2;
  const int y0 = gap + row * (cell + gap) + (cell - img.height) / 2;
  for (int c = 0; c < 3; ++c)
    for (int y = 0; y < img.height; ++y)
      for (int x = 0; x < img.width; ++x) sheet.at(c, y0 + y, x0 + x) = img.at(c, y, x);
}

int run_contact_sheet(int argc, char** argv) {
  std::string contents_arg, styles_arg, output, device;
  int size = 256;
  float alpha = 1.0f;
  po::options_description desc("stylerf contact-sheet -o sheet.png [options]");
  desc.add_options()("help,h", "show this help")("contents", po::value(&contents_arg),
                                                 "comma-separated content images (default: lego r_0, fern, horns)")(
      "styles", po::value(&styles_arg), "comma-separated style images (default: four from <data>/styles)")(
      "output,o", po::value(&output), "output PNG")("size", po::value(&size)->default_value(256),
                                                    "cell size: longer side of every image")(
      "alpha", po::value(&alpha)->default_value(1.0f), "stylisation strength in [0,1]")(
      "device", po::value(&device), stylerf::cli::kDeviceHelp);
  po::variables_map vm;
  po::store(po::parse_command_line(argc, argv, desc), vm);
  po::notify(vm);
  if (vm.count("help")) {
    stylerf::cli::print_help(std::cout, "contact-sheet", desc);
    return 0;
  }
  if (output.empty()) {
    std::cerr << "stylerf contact-sheet: -o is required\n" << desc;
    return 2;
  }
  if (size < 8) throw std::runtime_error("--size must be at least 8");
  const std::string data = data_dir();
  std::vector<std::string> contents =
      contents_arg.empty() ? std::vector<std::string>{data + "/scenes/blender/lego/train/r_0.png",
                                                      first_image(data + "/scenes/llff/fern/images_8"),
                                                      first_image(data + "/scenes/llff/horns/images_8")}
                           : split_list(contents_arg);
  std::vector<std::string> styles =
      styles_arg.empty() ? std::vector<std::string>{data + "/styles/fns_wave.jpg", data + "/styles/ns_the_scream.jpg",
                                                    data + "/styles/fns_udnie.jpg", data + "/styles/fns_mosaic.jpg"}
                         : split_list(styles_arg);
  if (contents.empty() || styles.empty()) throw std::runtime_error("need at least one content and one style");

  stylerf::cli::init_runtime(device, false);
  auto model = stylerf::style::AdainModel::load_default();
  const int gap = 4;
  Image sheet;
  sheet.width = gap + int(styles.size() + 1) * (size + gap);
  sheet.height = gap + int(contents.size() + 1) * (size + gap);
  sheet.data.assign(size_t(3) * sheet.width * sheet.height, 1.0f);  // white background

  std::vector<Image> style_imgs, content_imgs;
  for (size_t j = 0; j < styles.size(); ++j) {
    style_imgs.push_back(stylerf::style::load_image_for_adain(styles[j], size));
    paste(sheet, style_imgs.back(), 0, int(j) + 1, size, gap);
  }
  for (size_t i = 0; i < contents.size(); ++i) {
    content_imgs.push_back(stylerf::style::load_image_for_adain(contents[i], size));
    paste(sheet, content_imgs.back(), int(i) + 1, 0, size, gap);
  }
  for (size_t i = 0; i < contents.size(); ++i)
    for (size_t j = 0; j < styles.size(); ++j) {
      auto t0 = std::chrono::steady_clock::now();
      Image out = stylerf::io::from_tensor(stylerf::style::adain_stylize(
          model, stylerf::io::to_tensor(content_imgs[i]), stylerf::io::to_tensor(style_imgs[j]), alpha));
      for (float& v : out.data) v = std::min(1.0f, std::max(0.0f, v));
      paste(sheet, out, int(i) + 1, int(j) + 1, size, gap);
      std::cout << fs::path(contents[i]).filename().string() << " x " << fs::path(styles[j]).filename().string()
                << ": " << std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() << " s\n";
    }
  stylerf::io::save_png(output, sheet);
  std::cout << "wrote " << output << " (" << sheet.width << "x" << sheet.height << ")\n";
  return 0;
}

stylerf::cli::Register reg("contact-sheet", run_contact_sheet);

}  // namespace
