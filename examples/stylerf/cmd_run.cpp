// stylerf run --scene DIR --styles DIR -o OUT [--minutes M] [--recipe fast|paper] [--stylize IMG ...]:
// the whole pipeline in one command. It trains the three stages (density, features, style) within one
// time budget, then evaluates and shows what it made:
//   OUT/density.ckpt, features.ckpt, style.ckpt     the checkpoints (each a stage's own command's output)
//   OUT/density_test, features_test                 held-out views rendered, with PSNR (metrics.json)
//   OUT/style_eval                                   truth | ours | 2D AdaIN per held-out style
//   OUT/videos                                       zero-shot camera paths of each --stylize image (mp4)
//   OUT/mix                                          the 5 x 5 four-corner style interpolation sheet
//   OUT/consistency                                  eval table: StyleRF vs per-frame 2D AdaIN
//   OUT/summary.json, OUT/index.html                 the numbers and pictures in one place
//   OUT/logs/<step>.log, OUT/steps.json              each step's output, and what resuming keeps
// Each step is skipped when OUT already holds its output for the same inputs and options, so a killed
// run resumes (examples/stylerf/pipeline_steps.hpp).
#include <boost/program_options.hpp>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <sstream>

#include "examples/stylerf/commands.hpp"
#include "examples/stylerf/pipeline_steps.hpp"
#include "examples/stylerf/run_report.hpp"
#include "host/error.hpp"
#include "lib/io/image.hpp"
#include "lib/style/style_image.hpp"
#include "lib/train/recipes.hpp"
#include "lib/train/style_trainer.hpp"

namespace po = boost::program_options;
namespace fs = std::filesystem;

namespace stylerf::cli {
namespace {

using host::Error;

std::string num(double v) {
  std::ostringstream o;
  o << std::setprecision(6) << v;
  return o.str();
}

// How a run's minutes are spent. The training stages share what evaluation leaves, in the proportions of
// the runs that met the stages' floors on lego and fern (10 + 30 + 45 minutes: density, features, style).
struct Budget {
  double density = 0, features = 0, style = 0;  // minutes
  std::vector<int> iters;                        // --stage-iters: iterations per stage instead of minutes
};

// "D,F,S": three positive numbers.
std::vector<double> three_numbers(const std::string& text, const char* flag) {
  std::vector<double> v(3);
  char c1 = 0, c2 = 0;
  std::istringstream in(text);
  if (!(in >> v[0] >> c1 >> v[1] >> c2 >> v[2]) || c1 != ',' || c2 != ',' || !(v[0] > 0) || !(v[1] > 0) ||
      !(v[2] > 0) || !in.eof())
    throw Error(std::string(flag) + " takes three positive numbers D,F,S (density, features, style), got '" + text + "'");
  return v;
}

Budget split_budget(double minutes, const std::string& stage_minutes, const std::string& stage_iters) {
  Budget b;
  if (!stage_minutes.empty() && !stage_iters.empty()) throw Error("--stage-minutes and --stage-iters exclude each other");
  if (!stage_iters.empty()) {
    for (double v : three_numbers(stage_iters, "--stage-iters")) {
      if (v != std::floor(v) || v > 1e7) throw Error("--stage-iters takes whole numbers of iterations, got '" + stage_iters + "'");
      b.iters.push_back(int(v));
    }
    return b;
  }
  if (!stage_minutes.empty()) {
    const auto v = three_numbers(stage_minutes, "--stage-minutes");
    b.density = v[0], b.features = v[1], b.style = v[2];
    return b;
  }
  if (!(minutes > 0) || !std::isfinite(minutes)) throw Error("--minutes must be a positive number of minutes");
  const double train = minutes * 0.9;  // the last tenth: evaluation, videos and the report
  b.density = train * 10.0 / 85.0;
  b.features = train * 30.0 / 85.0;
  b.style = train * 45.0 / 85.0;
  return b;
}

struct RunOptions {
  std::string scene, styles, out, recipe = "fast", device, stage_minutes, stage_iters;
  std::vector<std::string> stylize;
  int downsample = 0, holdout = 12, frames = 60, eval_views = 5, table_frames = 16, max_videos = 3;
  double minutes = 90;
  bool check = false;
};

std::vector<std::string> common(const RunOptions& o) {
  return o.device.empty() ? std::vector<std::string>{} : std::vector<std::string>{"--device", o.device};
}

template <class... T>
std::vector<std::string> args(const RunOptions& o, T... a) {
  std::vector<std::string> v{a...};
  for (const auto& c : common(o)) v.push_back(c);
  return v;
}

// The options; returns false (after printing the help) when there is nothing to run, with `rc` to exit with.
bool parse_run_options(int argc, char** argv, RunOptions& o, int& rc) {
  po::options_description desc("stylerf run --scene DIR --styles DIR -o OUT [options]");
  desc.add_options()("help,h", "show this help")("scene", po::value(&o.scene), "the scene (Blender, LLFF, COLMAP or nerfstudio folder)")(
      "styles", po::value(&o.styles), "folder of training style images (some are held out)")(
      "output,o", po::value(&o.out), "output folder (a run there before is resumed)")(
      "minutes", po::value(&o.minutes)->default_value(90), "the whole run's time budget")(
      "stage-minutes", po::value(&o.stage_minutes), "D,F,S: each training stage's minutes (replaces --minutes' split)")(
      "stage-iters", po::value(&o.stage_iters),
      "D,F,S: each training stage's iterations instead of minutes (the same result on any machine)")(
      "recipe", po::value(&o.recipe)->default_value("fast"),
      "fast: the best measured recipe (fast feature profile; docs/results.md) | paper: the paper's settings")(
      "downsample", po::value(&o.downsample)->default_value(0), "image downsample (0: the scene's default, the paper's resolution: Blender 1, LLFF 4)")(
      "holdout-styles", po::value(&o.holdout)->default_value(12), "styles held out of training (evaluated)")(
      "stylize", po::value(&o.stylize)->multitoken(),
      "style images for the zero-shot videos and the consistency table (default: held-out styles)")(
      "max-videos", po::value(&o.max_videos)->default_value(3), "held-out styles given videos when --stylize is not")(
      "frames", po::value(&o.frames)->default_value(60), "frames of each video's camera path")(
      "eval-views", po::value(&o.eval_views)->default_value(5), "test views for the style evaluation")(
      "table-frames", po::value(&o.table_frames)->default_value(16), "frames scored by the consistency table")(
      "check", po::bool_switch(&o.check),
      "exit non-zero when the result is degenerate (style loss > 1.5x AdaIN's, mix corners < 0.01 apart, "
      "short-range RMSE > 0.8x AdaIN's)")("device", po::value(&o.device), "OpenCL device");
  po::variables_map vm;
  po::store(po::parse_command_line(argc, argv, desc), vm);
  po::notify(vm);
  if (vm.count("help") || o.scene.empty() || o.styles.empty() || o.out.empty()) {
    std::cout << desc;
    rc = vm.count("help") ? 0 : 2;
    return false;
  }
  train::parse_recipe(o.recipe);  // refused before any work
  if (!fs::is_directory(o.scene)) throw Error("--scene " + o.scene + " is not a folder");
  if (!fs::is_directory(o.styles)) throw Error("--styles " + o.styles + " is not a folder");
  for (const auto& s : o.stylize) {
    const std::string why = io::image_unreadable_reason(s);
    if (!why.empty()) throw Error("--stylize " + s + ": " + why);
  }
  if (o.frames < 2 || o.eval_views < 1 || o.table_frames < 8 || o.max_videos < 1 || o.holdout < 1)
    throw Error("--frames must be >= 2, --eval-views, --max-videos and --holdout-styles >= 1, --table-frames >= 8");
  return true;
}

// Which styles the videos, the consistency table and the mix sheet show.
struct Shown {
  std::vector<std::string> styles, corners;
};

Shown shown_styles(const RunOptions& o) {
  const auto styles = train::StyleSet::from_dir(o.styles, o.holdout, nullptr);
  Shown r;
  r.styles = o.stylize;
  if (r.styles.empty())
    for (size_t i = 0; i < styles.holdout.size() && int(i) < o.max_videos; ++i) r.styles.push_back(styles.holdout[i]);
  // The mix sheet's four corners: the shown styles first, then held-out ones, then training ones.
  r.corners = r.styles;
  for (const auto* list : {&styles.holdout, &styles.train})
    for (const auto& s : *list)
      if (r.corners.size() < 4 && std::find(r.corners.begin(), r.corners.end(), s) == r.corners.end())
        r.corners.push_back(s);
  if (r.corners.size() < 4) throw Error("--styles " + o.styles + ": the mix sheet needs 4 style images");
  r.corners.resize(4);
  return r;
}

int run_pipeline(int argc, char** argv) {
  RunOptions o;
  int rc = 0;
  if (!parse_run_options(argc, argv, o, rc)) return rc;
  const Budget budget = split_budget(o.minutes, o.stage_minutes, o.stage_iters);
  const Shown picked = shown_styles(o);
  const std::vector<std::string>& shown = picked.styles;
  const std::vector<std::string>& corners = picked.corners;

  fs::create_directories(o.out);
  const fs::path out(o.out);
  const std::string self = fs::read_symlink("/proc/self/exe").string();
  PipelineSteps steps(o.out, self);
  if (budget.iters.empty())
    std::cout << "stylerf run: recipe " << o.recipe << "; training minutes: density " << std::fixed
              << std::setprecision(1) << budget.density << ", features " << budget.features << ", style "
              << budget.style << std::endl;
  else
    std::cout << "stylerf run: recipe " << o.recipe << "; training iterations: density " << budget.iters[0]
              << ", features " << budget.iters[1] << ", style " << budget.iters[2] << std::endl;
  // Each stage trains for its minutes or its iterations.
  auto length = [&](int stage, double minutes) {
    return budget.iters.empty() ? std::vector<std::string>{"--minutes", num(minutes)}
                                : std::vector<std::string>{"--iters", std::to_string(budget.iters[size_t(stage)])};
  };
  const std::string scene_fp = folder_fingerprint(o.scene), styles_fp = folder_fingerprint(o.styles);
  const std::string d_ck = (out / "density.ckpt").string(), f_ck = (out / "features.ckpt").string(),
                    s_ck = (out / "style.ckpt").string();

  std::vector<std::string> density = args(o, "train-density", "--scene", o.scene, "--recipe", o.recipe, "--force",
                                          "-o", d_ck);
  if (o.downsample > 0) density.insert(density.end(), {"--downsample", std::to_string(o.downsample)});
  for (const auto& a : length(0, budget.density)) density.push_back(a);
  auto d = steps.run("density", density, d_ck, scene_fp);
  std::vector<std::string> features = args(o, "train-features", "--density", d_ck, "--recipe", o.recipe, "--force",
                                           "-o", f_ck);
  for (const auto& a : length(1, budget.features)) features.push_back(a);
  auto f = steps.run("features", features, f_ck, d.key);
  std::vector<std::string> style = args(o, "train-style", "--features", f_ck, "--styles", o.styles, "--holdout-styles",
                                        std::to_string(o.holdout), "--recipe", o.recipe, "--force", "-o", s_ck);
  for (const auto& a : length(2, budget.style)) style.push_back(a);
  auto s = steps.run("style", style, s_ck, f.key + styles_fp);

  const std::string upstream = s.key + d.key;
  steps.run("density_test", args(o, "render", "--ckpt", d_ck, "--views", "test", "-o", (out / "density_test").string()),
                      (out / "density_test/metrics.json").string(), d.key);
  steps.run("features_test",
                      args(o, "render", "--ckpt", f_ck, "--views", "test", "-o", (out / "features_test").string()),
                      (out / "features_test/metrics.json").string(), f.key);
  steps.run("style_eval",
                      args(o, "eval-style", "--ckpt", s_ck, "--views", std::to_string(o.eval_views), "--images",
                           (out / "style_eval").string(), "--json", (out / "style_eval.json").string()),
                      (out / "style_eval.json").string(), upstream);
  std::vector<std::string> vid = args(o, "stylize", "--ckpt", s_ck, "--views", "path", "--frames",
                                      std::to_string(o.frames), "--no-losses", "-o", (out / "videos").string());
  for (const auto& st : shown) vid.insert(vid.end(), {"--style", st});
  steps.run("videos", vid, (out / "videos/metrics.json").string(), upstream);
  steps.run("mix",
                      args(o, "stylize", "--ckpt", s_ck, "--views", "test", "--mix-grid",
                           corners[0] + "," + corners[1] + "," + corners[2] + "," + corners[3], "-o",
                           (out / "mix").string()),
                      (out / "mix/metrics.json").string(), upstream);
  std::vector<std::string> table = args(o, "eval", "table", "--scene-ckpts", d_ck + "," + s_ck, "--frames",
                                        std::to_string(o.table_frames), "-o", (out / "consistency").string(),
                                        "--styles");
  for (const auto& st : shown) table.push_back(st);
  steps.run("consistency", table, (out / "consistency/table.json").string(), upstream);

  RunReportInput in;
  in.out = o.out;
  in.recipe = o.recipe;
  in.scene = o.scene;
  in.minutes = !budget.iters.empty() ? 0.0 : o.stage_minutes.empty() ? o.minutes : budget.density + budget.features + budget.style;
  in.steps = steps.record();
  in.shown_styles = shown;
  in.corners = corners;
  const RunSummary summary = write_run_report(in);
  print_run_summary(summary, std::cout);
  if (o.check && !summary.failures.empty()) {
    std::cout << "stylerf run --check: the result is degenerate:\n";
    for (const auto& why : summary.failures) std::cout << "  " << why << "\n";
    return 3;
  }
  return 0;
}

Register reg("run", "the whole pipeline: density, features, style, then videos, mix sheet and consistency",
             run_pipeline);

}  // namespace
}  // namespace stylerf::cli
