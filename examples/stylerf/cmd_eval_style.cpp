// stylerf eval style --ckpt STYLE_CKPT [--styles DIR] [--max-views N] [-o DIR]: the style stage's
// yardstick. For the checkpoint's held-out styles (never trained on; or every image of --styles), the
// content and style losses of our stylised test views beside those of 2D AdaIN applied to the true views,
// by the same VGG and mask (lib/train/style_eval.hpp), per style and on average, with their ratio.
#include <boost/program_options.hpp>
#include <filesystem>
#include <iomanip>
#include <iostream>

#include "examples/stylerf/cli_checks.hpp"
#include "examples/stylerf/commands.hpp"
#include "examples/stylerf/help.hpp"
#include "examples/stylerf/refine_option.hpp"
#include "host/error.hpp"
#include "host/files.hpp"
#include "lib/model/block_refine.hpp"
#include "lib/scene/scene_meta.hpp"
#include "lib/train/style_eval.hpp"
#include "lib/train/style_trainer.hpp"

namespace po = boost::program_options;

namespace stylerf::cli {

using stylerf::host::Error;

// `stylerf eval style` (cmd_eval.cpp dispatches it).
int run_eval_style(int argc, char** argv) {
  namespace train = stylerf::train;
  std::string ckpt, styles_dir, images, json_path, device;
  int views = 5;
  std::string supersample_text = "0";
  float refine_contrast = stylerf::model::kRefineContrast;
  po::options_description desc("stylerf eval style --ckpt STYLE_CKPT [options]");
  desc.add_options()("help,h", "show this help")("ckpt", po::value(&ckpt), "style checkpoint (train-style)")(
      "styles", po::value(&styles_dir), "evaluate every image of this folder (default: the checkpoint's held-out styles)")(
      "max-views", po::value(&views)->default_value(5), "test views, evenly spaced (0: all)")(
      "output,o", po::value(&images), "folder for one PNG per style: truth | ours | AdaIN (first view)")(
      "json", po::value(&json_path), "also write the per-style losses and the ratios to this JSON file")(
      "supersample", stylerf::cli::supersample_value(&supersample_text), stylerf::cli::kSupersampleHelp)(
      "refine-contrast", stylerf::cli::refine_contrast_value(&refine_contrast), stylerf::cli::kRefineContrastHelp)(
      "device", po::value(&device), stylerf::cli::kDeviceHelp);
  apply_renamed_flags("eval style", argc, argv, {{"--views", "--max-views"}, {"--images", "--output"}});
  po::variables_map vm;
  po::store(po::parse_command_line(argc, argv, desc), vm);
  po::notify(vm);
  if (vm.count("help") || ckpt.empty()) {
    print_help(std::cout, "eval style", desc);
    return vm.count("help") ? 0 : 2;
  }
  if (views < 0) throw Error("--max-views must be >= 0");
  const int supersample = stylerf::cli::supersample_from(supersample_text);
  stylerf::cli::check_refine_contrast(refine_contrast);
  if (!images.empty()) std::filesystem::create_directories(images);
  stylerf::cli::init_runtime(device, false);
  const auto ck = stylerf::io::load_checkpoint(ckpt, "style");
  const auto model = stylerf::model::StyleModel::load(ck);
  const auto scene = stylerf::scene::open_scene_for(ck.meta.value("scene", nlohmann::json::object()), ckpt).scene;
  std::vector<std::string> styles;
  if (!styles_dir.empty()) {
    styles = train::StyleSet::from_dir(styles_dir, 0, &std::cout).train;
  } else {
    styles = train::StyleSet::from_json(ck.meta.at("styles")).holdout;
    if (styles.empty()) throw Error("checkpoint " + ckpt + " held out no styles; pass --styles DIR");
  }
  auto vgg = stylerf::nn::VggEncoder::load_default();
  auto adain = stylerf::style::AdainModel::load_default();
  train::StyleEvalOptions opt;
  opt.views = views;
  opt.supersample = supersample != 0 ? supersample : model.inference_supersample;
  opt.refine_contrast = refine_contrast;
  opt.image_dir = images;
  opt.log = &std::cout;
  const auto rows = train::evaluate_styles(model, vgg, adain, scene, styles, opt);
  double oc = 0, os = 0, ac = 0, as = 0;
  std::cout << std::fixed << std::setprecision(3) << "style                                     ours: content   style"
            << "   AdaIN: content   style\n";
  for (const auto& r : rows) {
    std::cout << std::left << std::setw(40) << r.style.substr(0, 40) << std::right << std::setw(15) << r.ours_content
              << std::setw(9) << r.ours_style << std::setw(16) << r.adain_content << std::setw(9) << r.adain_style << "\n";
    oc += r.ours_content, os += r.ours_style, ac += r.adain_content, as += r.adain_style;
  }
  const double k = double(std::max<size_t>(1, rows.size()));
  std::cout << "mean over " << rows.size() << " styles: ours content " << oc / k << " style " << os / k
            << "; AdaIN content " << ac / k << " style " << as / k << "\n"
            << "style loss ours / AdaIN = " << (os / k) / (as / k) << "  (content ours / AdaIN = " << (oc / k) / (ac / k)
            << ")" << std::endl;
  if (!json_path.empty()) {
    nlohmann::json per = nlohmann::json::array();
    for (const auto& r : rows)
      per.push_back({{"style", r.style},
                     {"ours_content", r.ours_content},
                     {"ours_style", r.ours_style},
                     {"adain_content", r.adain_content},
                     {"adain_style", r.adain_style},
                     {"style_ratio", r.ours_style / r.adain_style}});
    const nlohmann::json doc = {{"checkpoint", ckpt},
                                {"views", views},
                                {"supersample", stylerf::model::supersample_name(opt.supersample)},
                                {"refine_contrast", opt.supersample != 1 ? refine_contrast : 0.0f},
                                {"styles", per},
                                {"style_loss_ratio", (os / k) / (as / k)},
                                {"content_loss_ratio", (oc / k) / (ac / k)}};
    stylerf::host::write_file_atomic(json_path, doc.dump(2) + "\n");
  }
  // Where the style gap lies: relu1_1 / relu2_1 measure colour and fine texture, relu3_1 / relu4_1 larger
  // patterns. A blurred stylisation loses most at the low taps.
  const char* taps[] = {"relu1_1", "relu2_1", "relu3_1", "relu4_1"};
  std::cout << "style loss per VGG tap (mean over styles), ours / AdaIN:";
  for (size_t t = 0; t < 4; ++t) {
    double o = 0, a = 0;
    for (const auto& r : rows) o += r.ours_style_tap[t], a += r.adain_style_tap[t];
    std::cout << "  " << taps[t] << " " << o / k << " / " << a / k;
  }
  std::cout << std::endl;
  return 0;
}

}  // namespace stylerf::cli
