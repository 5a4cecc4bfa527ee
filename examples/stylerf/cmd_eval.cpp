// stylerf eval style|consistency|table: held-out styles against 2D AdaIN (cmd_eval_style.cpp), and the consistency metric of StyleRF's Table 1 by the scene's own geometry
// (lib/eval/consistency.hpp), for one method (consistency) or the paper's table (cmd_eval_table.cpp).
//
// stylerf eval consistency --ckpt CKPT --method rgb|adain|stylerf [--style IMG] [--scored-frames 16] --json F
//   rgb, adain: CKPT is a density checkpoint (its RGB frames; AdaIN stylises each one);
//   stylerf:    CKPT is a style checkpoint (zero-shot with --style).
// The frames are the first --scored-frames of the scene's default path of --path-frames (a video's spacing);
// every method is warped by the checkpoint's frozen geometry.
#include <boost/program_options.hpp>
#include <chrono>
#include <filesystem>
#include <iostream>

#include "examples/stylerf/command_index.hpp"
#include "examples/stylerf/commands.hpp"
#include "examples/stylerf/help.hpp"
#include "examples/stylerf/eval_setup.hpp"
#include "examples/stylerf/refine_option.hpp"
#include "examples/stylerf/strength_option.hpp"
#include "host/error.hpp"
#include "host/files.hpp"
#include "lib/eval/path_frames.hpp"
#include "lib/model/density_model.hpp"
#include "lib/model/scene_style_stats.hpp"
#include "lib/model/style_model.hpp"
#include "lib/style/style_encoder.hpp"
#include "lib/style/style_image.hpp"

namespace po = boost::program_options;
namespace fs = std::filesystem;

namespace stylerf::cli {
int run_eval_table(int argc, char** argv);  // cmd_eval_table.cpp
int run_eval_style(int argc, char** argv);  // cmd_eval_style.cpp
}

namespace {

using stylerf::host::Error;
using Clock = std::chrono::steady_clock;
namespace cli = stylerf::cli;
namespace eval = stylerf::eval;
namespace model = stylerf::model;

using stylerf::cli::seconds_since;

// The stylised path by a style checkpoint, for one style image (encoded through the cache).
std::vector<stylerf::io::Image> stylised_frames(const model::StyleModel& m, const stylerf::scene::Scene& scene,
                                                const std::vector<stylerf::scene::Camera>& cams,
                                                const std::string& style_path, const cli::PathOptions& p) {
  stylerf::nn::VggEncoder vgg = stylerf::nn::VggEncoder::load_default();
  stylerf::style::StyleEncoder enc(m.dst, vgg, stylerf::style::StyleEncoder::default_cache_dir());
  stylerf::style::StyleCode code = enc.encode(style_path).code;
  const int rays = p.supersample != 0 ? p.supersample : m.inference_supersample;
  stylerf::model::SceneStyleStats(m, scene, stylerf::model::SceneStyleStats::kDefaultViews, rays, p.refine_contrast)
      .attach(code);
  return eval::stylerf_frames(m, scene, cams, code, m.features.geo.has_background, p.chunk, rays, p.refine_contrast);
}

// The density checkpoint's RGB path, or (with a style image) per-frame 2D AdaIN of it.
std::vector<stylerf::io::Image> unstylised_frames(const model::DensityModel& density,
                                                  const stylerf::scene::Scene& scene,
                                                  const std::vector<stylerf::scene::Camera>& cams,
                                                  const std::string& adain_style, const cli::PathOptions& p) {
  auto frames = eval::rgb_frames(density, scene, cams, p.chunk);
  if (adain_style.empty()) return frames;
  auto adain = stylerf::style::AdainModel::load_default();
  return eval::adain_frames(adain, frames, eval::load_style_for_eval(adain_style));
}

int run_consistency(int argc, char** argv) {
  std::string ckpt, method, style_path, json_path, out_dir, scene_dir, device, lpips_net = eval::lpips_net_name(eval::kDefaultLpipsNet);
  cli::PathOptions p;
  bool no_lpips = false;
  po::options_description desc("stylerf eval consistency --ckpt CKPT --method rgb|adain|stylerf [--style IMG] [options]");
  desc.add_options()("help,h", "show this help")(
      "ckpt", po::value(&ckpt), "density checkpoint (rgb, adain) or style checkpoint (stylerf)")(
      "method", po::value(&method), "rgb (the floor) | adain (per-frame 2D AdaIN of the RGB frames) | stylerf")(
      "style", po::value(&style_path), "style image (adain, stylerf)")(
      "scored-frames", po::value(&p.frames)->default_value(16), "frames compared: the first N of the path")(
      "path-frames", po::value(&p.path_frames)->default_value(120), "frames of the whole path (their spacing)")(
      "size", po::value(&p.size)->default_value(0), "longer image side (0: the scene's)")(
      "depth-tol", cli::value_shown(&p.depth_tolerance), "occlusion test: relative depth tolerance")(
      "no-lpips", po::bool_switch(&no_lpips), "RMSE only")(
      "lpips-net", po::value(&lpips_net)->default_value(lpips_net), "LPIPS trunk: vgg | alex")("json", po::value(&json_path), "write the scores here")(
      "output,o", po::value(&out_dir), "also write the frames (PNG) here")(
      "scene", po::value(&scene_dir), "scene directory (default: the checkpoint's)")(
      "chunk", po::value(&p.chunk)->default_value(8192), "rays per renderer call")(
      "supersample", stylerf::cli::supersample_value(&p.supersample_text), stylerf::cli::kSupersampleHelp)(
      "refine-contrast", stylerf::cli::refine_contrast_value(&p.refine_contrast), stylerf::cli::kRefineContrastHelp)(
      "strength", stylerf::cli::strength_value(&p.strength), stylerf::cli::kStrengthHelp)(
      "device", po::value(&device), stylerf::cli::kDeviceHelp);
  cli::apply_renamed_flags("eval consistency", argc, argv, {{"--frames", "--scored-frames"}});
  po::variables_map vm;
  po::store(po::parse_command_line(argc, argv, desc), vm);
  po::notify(vm);
  if (vm.count("help") || ckpt.empty()) {
    cli::print_help(std::cout, "eval consistency", desc);
    return vm.count("help") ? 0 : 2;
  }
  // ---- options, checked before anything loads ----
  if (method != "rgb" && method != "adain" && method != "stylerf")
    throw Error("--method must be rgb, adain or stylerf (got '" + method + "')");
  if (method != "rgb" && style_path.empty()) throw Error("--method " + method + " needs --style IMG");
  if (method == "rgb" && !style_path.empty()) throw Error("--method rgb takes no --style (it is the unstylised floor)");
  if (!style_path.empty()) {
    const std::string why = stylerf::io::image_unreadable_reason(style_path);
    if (!why.empty()) throw Error("--style " + style_path + ": " + why);
  }
  cli::check_path_options(p);
  const eval::LpipsNet net = eval::parse_lpips_net(lpips_net);

  cli::init_runtime(device, false);
  const auto ck = stylerf::io::load_checkpoint(ckpt, "");
  const std::string want = method == "stylerf" ? "style" : "density";
  if (ck.kind != want)
    throw Error("--method " + method + " needs a " + want + " checkpoint (" +
                (want == "style" ? "train-style" : "train-density") + "); " + ckpt + " holds a '" + ck.kind + "' stage");
  const auto scene = cli::scene_of_checkpoint(ck, scene_dir);
  std::unique_ptr<model::DensityModel> density;
  std::unique_ptr<model::StyleModel> styled;
  if (want == "density")
    density = std::make_unique<model::DensityModel>(model::load_model(ck));
  else {
    styled = std::make_unique<model::StyleModel>(model::StyleModel::load(ck));
    cli::apply_strength(*styled, p.strength);
  }
  const model::Geometry& geo = density ? density->geo : styled->features.geo;
  std::unique_ptr<eval::Lpips> lpips;
  if (!no_lpips) lpips = std::make_unique<eval::Lpips>(eval::Lpips::load_default(net));

  const auto t0 = Clock::now();
  const cli::PathSetup path = cli::path_setup(geo, scene, p);
  std::cout << "geometry: " << path.cams.size() << " frames of " << path.cams.front().width << "x"
            << path.cams.front().height << " rendered and warped in " << path.seconds << " s\n";
  const auto t1 = Clock::now();
  const std::vector<stylerf::io::Image> frames =
      method == "stylerf" ? stylised_frames(*styled, scene, path.cams, style_path, p)
                          : unstylised_frames(*density, scene, path.cams, method == "adain" ? style_path : "", p);
  const double render_s = seconds_since(t1);
  const auto t2 = Clock::now();
  const auto dist = cli::lpips_distance(lpips.get());
  const auto score = eval::score_frames(frames, path.warps, dist.get());
  const double score_s = seconds_since(t2);
  std::cout << method << ": " << cli::score_line(score) << "\n"
            << "  frames rendered in " << render_s << " s, scored in " << score_s << " s\n";
  if (!out_dir.empty()) {
    fs::create_directories(out_dir);
    for (size_t i = 0; i < frames.size(); ++i)
      stylerf::io::save_png((fs::path(out_dir) / ("frame_" + std::to_string(1000 + i).substr(1) + ".png")).string(),
                            frames[i]);
  }
  if (!json_path.empty()) {
    nlohmann::json doc = {{"checkpoint", ckpt},
                          {"scene", scene.root},
                          {"method", method},
                          {"style", style_path},
                          {"frames", p.frames},
                          {"path_frames", p.path_frames},
                          {"size", {path.cams.front().width, path.cams.front().height}},
                          {"depth_tolerance", p.depth_tolerance},
                          {"lpips", lpips ? lpips_net + " (v0.1), masked: see lib/eval/consistency.hpp" : "not measured"},
                          {"score", score.to_json()},
                          {"seconds", {{"geometry", path.seconds}, {"frames", render_s}, {"scoring", score_s},
                                       {"total", seconds_since(t0)}}}};
    stylerf::host::write_file_atomic(json_path, doc.dump(2) + "\n");
    std::cout << "-> " << json_path << "\n";
  }
  return 0;
}

// `stylerf eval`'s own page: its subcommands (from command_index.cpp), then its examples.
std::string eval_usage() {
  std::string usage = "usage: stylerf eval style|consistency|table [options]   (stylerf eval <what> --help)\n\nsubcommands:\n";
  for (const cli::CommandInfo* sub : cli::subcommands_of("eval")) {
    const std::string name = sub->name.substr(5);
    usage += "  " + name + std::string(13 - std::min<size_t>(12, name.size()), ' ') + sub->summary + "\n";
  }
  return usage + "\n" + cli::examples_block("eval");
}

int run_eval(int argc, char** argv) {
  if (argc < 2 || std::string(argv[1]) == "--help" || std::string(argv[1]) == "-h") {
    (argc < 2 ? std::cerr : std::cout) << eval_usage();
    return argc < 2 ? 2 : 0;
  }
  const std::string what = argv[1];
  if (what == "style") return cli::run_eval_style(argc - 1, argv + 1);
  if (what == "consistency") return run_consistency(argc - 1, argv + 1);
  if (what == "table") return cli::run_eval_table(argc - 1, argv + 1);
  throw Error("eval: unknown '" + what + "'\n" + eval_usage());
}

cli::Register reg("eval", run_eval);

}  // namespace
