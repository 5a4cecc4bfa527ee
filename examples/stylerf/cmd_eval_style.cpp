// stylerf eval style --ckpt STYLE_CKPT [--styles DIR] [--max-views N] [-o DIR]: the style stage's
// yardstick. For the checkpoint's held-out styles (never trained on; or every image of --styles), the
// content and style losses of our stylised test views beside those of 2D AdaIN applied to the true views,
// by the same VGG and mask (lib/train/style_eval.hpp), per style and on average, with their ratio; and the
// structure score, LPIPS(true view, stylised view) of ours and of AdaIN's, with its ratio.
#include <boost/program_options.hpp>
#include <filesystem>
#include <iomanip>
#include <iostream>

#include "examples/stylerf/cli_checks.hpp"
#include "examples/stylerf/commands.hpp"
#include "examples/stylerf/help.hpp"
#include "examples/stylerf/rank_outputs.hpp"
#include "examples/stylerf/refine_option.hpp"
#include "examples/stylerf/strength_option.hpp"
#include "host/dist.hpp"
#include "host/error.hpp"
#include "host/files.hpp"
#include "lib/model/block_refine.hpp"
#include "lib/scene/scene_meta.hpp"
#include "lib/train/style_eval.hpp"
#include "lib/train/style_trainer.hpp"

namespace po = boost::program_options;

namespace stylerf::cli {

using stylerf::host::Error;

namespace {

// Means over the styles of each column of the evaluation; `structure` when the LPIPS columns were measured.
struct StyleMeans {
  double ours_content = 0, ours_style = 0, adain_content = 0, adain_style = 0, ours_lpips = 0, adain_lpips = 0;
  bool structure = false;
};

StyleMeans style_means(const std::vector<stylerf::train::StyleEvalRow>& rows) {
  StyleMeans m;
  const double k = double(std::max<size_t>(1, rows.size()));
  for (const auto& r : rows) {
    m.ours_content += r.ours_content / k, m.ours_style += r.ours_style / k;
    m.adain_content += r.adain_content / k, m.adain_style += r.adain_style / k;
    m.ours_lpips += r.ours_lpips / k, m.adain_lpips += r.adain_lpips / k;
  }
  m.structure = !rows.empty() && rows[0].structure_views > 0;
  return m;
}

// A row and back, every field, for the ranks' rows to reach rank 0 ("view": its style's place in the list).
nlohmann::json row_to_json(const stylerf::train::StyleEvalRow& r, size_t index) {
  return {{"view", index},
          {"style", r.style},
          {"losses", {r.ours_content, r.ours_style, r.adain_content, r.adain_style, r.ours_lpips, r.adain_lpips}},
          {"ours_taps", r.ours_style_tap},
          {"adain_taps", r.adain_style_tap},
          {"structure_views", r.structure_views},
          {"vgg_map", {r.vgg_map_content, r.vgg_map_style, r.vgg_map_lpips}}};
}

stylerf::train::StyleEvalRow row_from_json(const nlohmann::json& j) {
  stylerf::train::StyleEvalRow r;
  r.style = j.at("style").get<std::string>();
  const auto l = j.at("losses").get<std::vector<double>>();
  r.ours_content = l.at(0), r.ours_style = l.at(1), r.adain_content = l.at(2), r.adain_style = l.at(3);
  r.ours_lpips = l.at(4), r.adain_lpips = l.at(5);
  r.ours_style_tap = j.at("ours_taps").get<decltype(r.ours_style_tap)>();
  r.adain_style_tap = j.at("adain_taps").get<decltype(r.adain_style_tap)>();
  r.structure_views = j.at("structure_views").get<int>();
  const auto v = j.at("vgg_map").get<std::vector<double>>();
  r.vgg_map_content = v.at(0), r.vgg_map_style = v.at(1), r.vgg_map_lpips = v.at(2);
  return r;
}

// The styles dealt round robin over the ranks (lib/train/style_eval.hpp evaluates each rank's share), their
// sheets gathered under `images` and their rows on rank 0 in the list's order; the other ranks get none.
std::vector<stylerf::train::StyleEvalRow> evaluate_over_ranks(const stylerf::model::StyleModel& model,
                                                             stylerf::nn::VggEncoder& vgg,
                                                             stylerf::style::AdainModel& adain,
                                                             const stylerf::scene::Scene& scene,
                                                             const std::vector<std::string>& styles,
                                                             stylerf::train::StyleEvalOptions opt) {
  std::vector<std::string> mine;
  std::vector<size_t> index;
  for (size_t i = 0; i < styles.size(); ++i)
    if (my_view(i)) mine.push_back(styles[i]), index.push_back(i);
  const std::string images = opt.image_dir;
  if (!images.empty()) opt.image_dir = rank_output_dir(images);
  const auto rows = stylerf::train::evaluate_styles(model, vgg, adain, scene, mine, opt);
  if (!images.empty()) collect_rank_outputs(opt.image_dir, images);
  nlohmann::json js = nlohmann::json::array();
  for (size_t i = 0; i < rows.size(); ++i) js.push_back(row_to_json(rows[i], index[i]));
  std::vector<stylerf::train::StyleEvalRow> all;
  for (const auto& j : gather_view_rows(js)) all.push_back(row_from_json(j));
  return all;
}

// A value when it was measured, else JSON null.
nlohmann::json optional(bool measured, double v) { return measured ? nlohmann::json(v) : nlohmann::json(); }

nlohmann::json per_style_json(const std::vector<stylerf::train::StyleEvalRow>& rows) {
  nlohmann::json per = nlohmann::json::array();
  for (const auto& r : rows) {
    const bool s = r.structure_views > 0;
    per.push_back({{"style", r.style},
                   {"ours_content", r.ours_content},
                   {"ours_style", r.ours_style},
                   {"adain_content", r.adain_content},
                   {"adain_style", r.adain_style},
                   {"ours_lpips", optional(s, r.ours_lpips)},
                   {"adain_lpips", optional(s, r.adain_lpips)},
                   {"style_ratio", r.ours_style / r.adain_style},
                   {"content_ratio", r.ours_content / r.adain_content},
                   {"structure_lpips_ratio", optional(s, r.ours_lpips / r.adain_lpips)}});
  }
  return per;
}

void print_style_table(std::ostream& os, const std::vector<stylerf::train::StyleEvalRow>& rows, const StyleMeans& m,
                       const std::string& lpips_net, int lpips_min_side) {
  os << std::fixed << std::setprecision(3) << "style                                     ours: content   style   LPIPS"
     << "   AdaIN: content   style   LPIPS\n";
  for (const auto& r : rows)
    os << std::left << std::setw(40) << r.style.substr(0, 40) << std::right << std::setw(15) << r.ours_content
       << std::setw(9) << r.ours_style << std::setw(8) << r.ours_lpips << std::setw(16) << r.adain_content
       << std::setw(9) << r.adain_style << std::setw(8) << r.adain_lpips << "\n";
  os << "mean over " << rows.size() << " styles: ours content " << m.ours_content << " style " << m.ours_style
     << " LPIPS " << m.ours_lpips << "; AdaIN content " << m.adain_content << " style " << m.adain_style << " LPIPS "
     << m.adain_lpips << "\n"
     << "ours / AdaIN (lower is better): style loss " << m.ours_style / m.adain_style << "x, content loss "
     << m.ours_content / m.adain_content << "x, LPIPS to the true view ";
  if (m.structure)
    os << m.ours_lpips / m.adain_lpips << "x (" << lpips_net << ")\n";
  else
    os << "not measured (views below " << lpips_min_side << " px)\n";
  // Where the style gap lies: relu1_1 / relu2_1 measure colour and fine texture, relu3_1 / relu4_1 larger
  // patterns. A blurred stylisation loses most at the low taps.
  const char* taps[] = {"relu1_1", "relu2_1", "relu3_1", "relu4_1"};
  const double k = double(std::max<size_t>(1, rows.size()));
  os << "style loss per VGG tap (mean over styles), ours / AdaIN:";
  for (size_t t = 0; t < 4; ++t) {
    double o = 0, a = 0;
    for (const auto& r : rows) o += r.ours_style_tap[t], a += r.adain_style_tap[t];
    os << "  " << taps[t] << " " << o / k << " / " << a / k;
  }
  os << std::endl;
}

// With --vgg-map-row: the style module on the true views' own VGG maps, mean ratios to AdaIN's (JSON, printed).
nlohmann::json vgg_map_ratios(const std::vector<stylerf::train::StyleEvalRow>& rows, const StyleMeans& m) {
  double c = 0, s = 0, l = 0;
  for (const auto& r : rows) c += r.vgg_map_content, s += r.vgg_map_style, l += r.vgg_map_lpips;
  const double k = double(std::max<size_t>(1, rows.size()));
  return {{"style_loss_ratio", s / k / m.adain_style},
          {"content_loss_ratio", c / k / m.adain_content},
          {"structure_lpips_ratio", optional(m.structure, l / k / m.adain_lpips)}};
}

}  // namespace

// `stylerf eval style` (cmd_eval.cpp dispatches it).
int run_eval_style(int argc, char** argv) {
  namespace train = stylerf::train;
  std::string ckpt, styles_dir, images, json_path, device;
  std::string lpips_net = stylerf::eval::lpips_net_name(stylerf::eval::kDefaultLpipsNet);
  int views = 5, max_styles = 0;
  bool vgg_map_row = false;
  std::string supersample_text = "0";
  float refine_contrast = stylerf::model::kRefineContrast, strength = stylerf::cli::kCheckpointStrength;
  po::options_description desc("stylerf eval style --ckpt STYLE_CKPT [options]");
  desc.add_options()("help,h", "show this help")("ckpt", po::value(&ckpt), "style checkpoint (train-style)")(
      "styles", po::value(&styles_dir), "evaluate every image of this folder (default: the checkpoint's held-out styles)")(
      "max-views", po::value(&views)->default_value(5), "test views, evenly spaced (0: all)")(
      "max-styles", po::value(&max_styles)->default_value(0), "styles scored, evenly spaced in name order (0: all)")(
      "output,o", po::value(&images), "folder for one PNG per style: truth | ours | AdaIN (first view)")(
      "json", po::value(&json_path), "also write the per-style losses and the ratios to this JSON file")(
      "lpips-net", po::value(&lpips_net)->default_value(lpips_net), "LPIPS trunk of the structure score: vgg | alex")(
      "vgg-map-row", po::bool_switch(&vgg_map_row),
      "also score ours on each true view's own VGG relu3_1 map instead of the rendered one: the style module "
      "with perfect content, to tell what the radiance field's map loses from what the style loses")(
      "supersample", stylerf::cli::supersample_value(&supersample_text), stylerf::cli::kSupersampleHelp)(
      "refine-contrast", stylerf::cli::refine_contrast_value(&refine_contrast), stylerf::cli::kRefineContrastHelp)(
      "strength", stylerf::cli::strength_value(&strength), stylerf::cli::kStrengthHelp)(
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
  if (max_styles < 0) throw Error("--max-styles must be >= 0");
  const int supersample = stylerf::cli::supersample_from(supersample_text);
  stylerf::cli::check_refine_contrast(refine_contrast);
  if (!images.empty()) std::filesystem::create_directories(images);
  stylerf::cli::init_runtime(device, false);
  const auto ck = stylerf::io::load_checkpoint(ckpt, "style");
  auto model = stylerf::model::StyleModel::load(ck);
  stylerf::cli::apply_strength(model, strength);
  const auto scene = stylerf::scene::open_scene_for(ck.meta.value("scene", nlohmann::json::object()), ckpt).scene;
  std::vector<std::string> styles;
  if (!styles_dir.empty()) {
    styles = train::StyleSet::from_dir(styles_dir, 0, &std::cout).train;
  } else {
    styles = train::StyleSet::from_json(ck.meta.at("styles")).holdout;
    if (styles.empty()) throw Error("checkpoint " + ckpt + " held out no styles; pass --styles DIR");
  }
  if (max_styles > 0 && size_t(max_styles) < styles.size()) {
    std::vector<std::string> kept;
    for (int i = 0; i < max_styles; ++i) kept.push_back(styles[size_t(int64_t(i) * styles.size() / max_styles)]);
    styles.swap(kept);
  }
  auto vgg = stylerf::nn::VggEncoder::load_default();
  auto adain = stylerf::style::AdainModel::load_default();
  const auto lpips = stylerf::eval::Lpips::load_default(stylerf::eval::parse_lpips_net(lpips_net));
  train::StyleEvalOptions opt;
  opt.views = views;
  opt.supersample = supersample != 0 ? supersample : model.inference_supersample;
  opt.refine_contrast = refine_contrast;
  opt.image_dir = images;
  opt.lpips = &lpips;
  opt.vgg_map_row = vgg_map_row;
  opt.log = &std::cout;
  const auto rows = evaluate_over_ranks(model, vgg, adain, scene, styles, opt);
  if (!stylerf::host::Dist::world().root()) return 0;  // rank 0 reports
  const StyleMeans mean = style_means(rows);
  print_style_table(std::cout, rows, mean, lpips_net, lpips.min_side());
  const nlohmann::json on_maps = vgg_map_row ? vgg_map_ratios(rows, mean) : nlohmann::json();
  if (vgg_map_row)
    std::cout << "ours on the true views' VGG maps (no radiance field) / AdaIN: style loss "
              << on_maps["style_loss_ratio"].get<double>() << "x, content loss "
              << on_maps["content_loss_ratio"].get<double>() << "x, LPIPS to the true view "
              << (on_maps["structure_lpips_ratio"].is_null()
                      ? std::string("not measured")
                      : std::to_string(on_maps["structure_lpips_ratio"].get<double>()) + "x")
              << "\n";
  if (!json_path.empty()) {
    nlohmann::json doc = {{"checkpoint", ckpt},
                                {"views", views},
                                {"supersample", stylerf::model::supersample_name(opt.supersample)},
                                {"strength", model.strength},
                                {"refine_contrast", opt.supersample != 1 ? refine_contrast : 0.0f},
                                {"styles", per_style_json(rows)},
                                {"style_loss_ratio", mean.ours_style / mean.adain_style},
                                {"content_loss_ratio", mean.ours_content / mean.adain_content},
                                {"structure_lpips_net", lpips_net},
                                {"structure_lpips_ratio", optional(mean.structure, mean.ours_lpips / mean.adain_lpips)}};
    if (vgg_map_row) doc["on_vgg_maps"] = on_maps;
    stylerf::host::write_file_atomic(json_path, doc.dump(2) + "\n");
  }
  return 0;
}

}  // namespace stylerf::cli
