// stylerf lpips A.png B.png [--net vgg] [--mask M.png] [--device D] [--profile]
// Prints the LPIPS distance (VGG-16, v0.1 heads; lib/eval/lpips.hpp) between two images of the same size,
// or the masked LPIPS with a mask image (its grey level, the mean of R, G and B, is the weight in [0,1]).
// Weights: lpips_vgg16.safetensors, set up with `bash scripts/fetch_weights.sh`.
#include <boost/program_options.hpp>
#include <iomanip>
#include <iostream>
#include <stdexcept>

#include "examples/stylerf/commands.hpp"
#include "host/runtime.hpp"
#include "lib/eval/lpips.hpp"
#include "lib/io/image.hpp"
#include "lib/nn/weights.hpp"

namespace po = boost::program_options;
using namespace stylerf;

namespace {

std::string size_of(const io::Image& im) { return std::to_string(im.width) + "x" + std::to_string(im.height); }

int run_lpips(int argc, char** argv) {
  std::string a_path, b_path, net = "vgg", mask_path, device;
  bool profile = false;
  po::options_description desc("stylerf lpips A.png B.png [options]");
  desc.add_options()("help,h", "show this help")("net", po::value(&net)->default_value("vgg"),
                                                  "trunk: vgg (VGG-16; the only one built)")(
      "mask", po::value(&mask_path), "mask image, same size: compare only where it is bright (masked LPIPS)")(
      "device", po::value(&device), "OpenCL device: index, cpu|gpu|accelerator, or part of a name")(
      "profile", po::bool_switch(&profile), "print per-kernel times");
  po::options_description hidden;
  hidden.add_options()("a", po::value(&a_path))("b", po::value(&b_path));
  po::positional_options_description pos;
  pos.add("a", 1).add("b", 1);
  po::options_description all;
  all.add(desc).add(hidden);
  po::variables_map vm;
  po::store(po::command_line_parser(argc, argv).options(all).positional(pos).run(), vm);
  po::notify(vm);
  if (vm.count("help")) {
    std::cout << desc << "\nWeights: " << nn::weights_path(eval::kLpipsVggWeightsFile) << " (set up with `"
              << nn::kFetchWeightsCommand << "`)\n";
    return 0;
  }
  if (a_path.empty() || b_path.empty()) {
    std::cerr << "stylerf lpips: two images are required\n" << desc;
    return 2;
  }
  if (net == "alex")
    throw std::runtime_error("--net alex: only the VGG-16 LPIPS (--net vgg) is built; the AlexNet trunk needs "
                             "11x11 stride-4 and 5x5 convolutions and 3x3 stride-2 pooling, which stylerf has not");
  if (net != "vgg") throw std::runtime_error("--net " + net + ": unknown trunk (use vgg)");

  // Images (and their sizes) before the weights and the device: a wrong file is reported first.
  const io::Image a = io::load_image(a_path), b = io::load_image(b_path);
  if (a.width != b.width || a.height != b.height)
    throw std::runtime_error(a_path + " is " + size_of(a) + " but " + b_path + " is " + size_of(b) +
                             ": LPIPS compares images of the same size");
  if (a.width < eval::kLpipsMinSide || a.height < eval::kLpipsMinSide)
    throw std::runtime_error(a_path + " and " + b_path + " are " + size_of(a) + ": LPIPS needs at least " +
                             std::to_string(eval::kLpipsMinSide) + "x" + std::to_string(eval::kLpipsMinSide));
  std::vector<float> mask;
  if (!mask_path.empty()) {
    const io::Image m = io::load_image(mask_path);
    if (m.width != a.width || m.height != a.height)
      throw std::runtime_error("--mask " + mask_path + " is " + size_of(m) + " but the images are " + size_of(a));
    const size_t n = size_t(m.width) * m.height;
    mask.resize(n);
    for (size_t i = 0; i < n; ++i) mask[i] = (m.data[i] + m.data[n + i] + m.data[2 * n + i]) / 3.0f;
  }

  cli::init_runtime(device, profile);
  const eval::Lpips lpips = eval::Lpips::load_default();
  const double d = mask_path.empty() ? lpips.distance(a, b) : lpips.distance(a, b, mask);
  std::cout << std::fixed << std::setprecision(6) << d << "\n";
  if (profile) std::cout << host::Runtime::instance().timing_report();
  return 0;
}

cli::Register reg("lpips", "LPIPS distance between two images (VGG-16, v0.1; --mask for a masked LPIPS)", run_lpips);

}  // namespace
