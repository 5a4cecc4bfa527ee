// stylerf lpips A.png B.png [--lpips-net vgg|alex] [--mask M.png] [--device D] [--timing]
// Prints the LPIPS distance (v0.1 heads, VGG-16 or AlexNet trunk; lib/eval/lpips.hpp) between two images
// of the same size, or the masked LPIPS with a mask image (its grey level, the mean of R, G and B, is the
// weight in [0,1]). Weights: lpips_vgg16.safetensors / lpips_alex.safetensors, set up with
// `bash scripts/fetch_weights.sh`.
#include <boost/program_options.hpp>
#include <iomanip>
#include <iostream>
#include <stdexcept>

#include "examples/stylerf/commands.hpp"
#include "examples/stylerf/help.hpp"
#include "host/runtime.hpp"
#include "lib/eval/lpips.hpp"
#include "lib/io/image.hpp"
#include "lib/nn/weights.hpp"

namespace po = boost::program_options;
using namespace stylerf;

namespace {

std::string size_of(const io::Image& im) { return std::to_string(im.width) + "x" + std::to_string(im.height); }

int run_lpips(int argc, char** argv) {
  std::string a_path, b_path, net = eval::lpips_net_name(eval::kDefaultLpipsNet), mask_path, device;
  bool timing = false;
  po::options_description desc("stylerf lpips A.png B.png [options]");
  desc.add_options()("help,h", "show this help")("lpips-net", po::value(&net)->default_value(net),
                                                  "trunk: vgg (VGG-16) or alex (AlexNet)")(
      "mask", po::value(&mask_path), "mask image, same size: compare only where it is bright (masked LPIPS)")(
      "device", po::value(&device), stylerf::cli::kDeviceHelp)(
      "timing", po::bool_switch(&timing), "print per-kernel times at the end");
  po::options_description hidden;
  hidden.add_options()("a", po::value(&a_path))("b", po::value(&b_path));
  po::positional_options_description pos;
  pos.add("a", 1).add("b", 1);
  po::options_description all;
  all.add(desc).add(hidden);
  cli::apply_renamed_flags("lpips", argc, argv, {{"--profile", "--timing"}, {"--net", "--lpips-net"}});
  po::variables_map vm;
  po::store(po::command_line_parser(argc, argv).options(all).positional(pos).run(), vm);
  po::notify(vm);
  if (vm.count("help")) {
    cli::print_help(std::cout, "lpips", desc,
                    "Weights: " + nn::weights_path(eval::kLpipsVggWeightsFile) + " (vgg), " +
                        nn::weights_path(eval::kLpipsAlexWeightsFile) + " (alex); set up with `" +
                        nn::kFetchWeightsCommand + "`");
    return 0;
  }
  if (a_path.empty() || b_path.empty()) {
    std::cerr << "stylerf lpips: two images are required\n" << desc;
    return 2;
  }
  if (net != "vgg" && net != "alex") throw std::runtime_error("--lpips-net " + net + ": unknown trunk (use vgg or alex)");
  const eval::LpipsNet which = eval::parse_lpips_net(net);
  const int min_side = eval::lpips_min_side(which);

  // Images (and their sizes) before the weights and the device: a wrong file is reported first.
  const io::Image a = io::load_image(a_path), b = io::load_image(b_path);
  if (a.width != b.width || a.height != b.height)
    throw std::runtime_error(a_path + " is " + size_of(a) + " but " + b_path + " is " + size_of(b) +
                             ": LPIPS compares images of the same size");
  if (a.width < min_side || a.height < min_side)
    throw std::runtime_error(a_path + " and " + b_path + " are " + size_of(a) + ": LPIPS (--lpips-net " + net +
                             ") needs at least " + std::to_string(min_side) + "x" + std::to_string(min_side));
  std::vector<float> mask;
  if (!mask_path.empty()) {
    const io::Image m = io::load_image(mask_path);
    if (m.width != a.width || m.height != a.height)
      throw std::runtime_error("--mask " + mask_path + " is " + size_of(m) + " but the images are " + size_of(a));
    const size_t n = size_t(m.width) * m.height;
    mask.resize(n);
    for (size_t i = 0; i < n; ++i) mask[i] = (m.data[i] + m.data[n + i] + m.data[2 * n + i]) / 3.0f;
  }

  cli::init_runtime(device, timing);
  const eval::Lpips lpips = eval::Lpips::load_default(which);
  const double d = mask_path.empty() ? lpips.distance(a, b) : lpips.distance(a, b, mask);
  std::cout << std::fixed << std::setprecision(6) << d << "\n";
  if (timing) std::cout << host::Runtime::instance().timing_report();
  return 0;
}

cli::Register reg("lpips", run_lpips);

}  // namespace
