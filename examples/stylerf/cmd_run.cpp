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
// Under --minutes the run keeps to its budget at any image size: after the features it times one frame of
// this scene (OUT/probe), predicts the evaluation (lib/eval/eval_budget.hpp), gives the style stage what is
// left and, when the evaluation would not fit its share, renders fewer video frames or styles. With
// --stage-iters the stages train their iterations instead; given --minutes too, the evaluation is still
// fitted to it the same way (the plan's style minutes then only size the evaluation's share).
#include <boost/program_options.hpp>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "examples/stylerf/commands.hpp"
#include "examples/stylerf/help.hpp"
#include "examples/stylerf/pipeline_steps.hpp"
#include "examples/stylerf/run_provenance.hpp"
#include "examples/stylerf/run_report.hpp"
#include "lib/eval/eval_budget.hpp"
#include "host/dist.hpp"
#include "host/error.hpp"
#include "lib/io/process.hpp"
#include "lib/io/image.hpp"
#include "lib/model/map_decoder.hpp"
#include "lib/model/scene_style_stats.hpp"
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
// the runs with the best measured results on lego and fern (10 + 30 + 45 minutes: density, features, style).
// 10 : 20 : 55 measured neutral on fern 1/8's style loss and cost 0.5 dB of its decoded views
// (docs/experiments.md).
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
  if (!stage_iters.empty())
    for (double v : three_numbers(stage_iters, "--stage-iters")) {
      if (v != std::floor(v) || v > 1e7) throw Error("--stage-iters takes whole numbers of iterations, got '" + stage_iters + "'");
      b.iters.push_back(int(v));
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
  b.style = train * 45.0 / 85.0;  // with --stage-iters: the style share the evaluation's plan assumes
  return b;
}

struct RunOptions {
  std::string scene, styles, out, recipe = "fast", device, stage_minutes, stage_iters, mpirun = "mpirun";
  std::vector<std::string> stylize;
  int ranks = 1;  // >1: the steps that split their work run under mpirun on this many ranks
  int downsample = 0, holdout = 12, frames = 60, eval_views = 5, table_frames = 16, max_videos = 3;
  double minutes = 90;
  bool minutes_given = false;  // --minutes on the command line (with --stage-iters: fit the evaluation to it)
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

// "mpirun --hostfile hosts" -> its words (no quoting: a launcher's options do not need it).
std::vector<std::string> launcher_words(const std::string& s) {
  std::vector<std::string> w;
  std::istringstream in(s);
  for (std::string x; in >> x;) w.push_back(x);
  return w;
}

// The options; returns false (after printing the help) when there is nothing to run, with `rc` to exit with.
bool parse_run_options(int argc, char** argv, RunOptions& o, int& rc) {
  po::options_description desc("stylerf run --scene DIR --styles DIR -o OUT [options]");
  desc.add_options()("help,h", "show this help")("scene", po::value(&o.scene), "the scene (Blender, LLFF, COLMAP or nerfstudio folder)")(
      "styles", po::value(&o.styles), "folder of training style images (some are held out)")(
      "output,o", po::value(&o.out), "output folder (a run there before is resumed)")(
      "minutes", po::value(&o.minutes)->default_value(90), "the whole run's time budget in minutes")(
      "stage-minutes", po::value(&o.stage_minutes), "D,F,S: each training stage's minutes (replaces --minutes' split)")(
      "stage-iters", po::value(&o.stage_iters),
      "D,F,S: each training stage's iterations instead of minutes (the same result on any machine; with "
      "--minutes, the evaluation is still fitted to it)")(
      "recipe", po::value(&o.recipe)->default_value("fast"),
      "fast: the best measured recipe (fast feature profile; docs/results.md) | paper: the paper's settings")(
      "downsample", po::value(&o.downsample)->default_value(0), "image downsample (0: the scene's default, the paper's resolution: Blender 1, LLFF 4)")(
      "holdout-styles", po::value(&o.holdout)->default_value(12), "styles held out of training (evaluated)")(
      "stylize", po::value(&o.stylize)->multitoken(),
      "style images for the zero-shot videos and the consistency table (default: held-out styles)")(
      "max-videos", po::value(&o.max_videos)->default_value(3), "held-out styles given videos when --stylize is not")(
      "frames", po::value(&o.frames)->default_value(60), "frames of each video's camera path")(
      "eval-views", po::value(&o.eval_views)->default_value(5),
      "held-out test views each stage is scored and shown on, evenly spaced (0: all)")(
      "table-frames", po::value(&o.table_frames)->default_value(16), "frames scored by the consistency table")(
      "check", po::bool_switch(&o.check),
      "exit non-zero when the result is degenerate (style loss > 1.5x AdaIN's, mix corners < 0.01 apart, "
      "short-range RMSE > 0.8x AdaIN's)")(
      "ranks", po::value(&o.ranks)->default_value(1),
      "MPI ranks, one device each: the training stages, the videos, eval style and the consistency table run "
      "under mpirun -np N (the other steps as one process)")(
      "mpirun", po::value(&o.mpirun)->default_value("mpirun"),
      "the launcher of --ranks' steps with its options (\"mpirun --hostfile hosts --bind-to core\"); it is given "
      "-np N")("device", po::value(&o.device), stylerf::cli::kDeviceHelp);
  po::variables_map vm;
  po::store(po::parse_command_line(argc, argv, desc), vm);
  po::notify(vm);
  o.minutes_given = !vm["minutes"].defaulted();
  if (vm.count("help") || o.scene.empty() || o.styles.empty() || o.out.empty()) {
    stylerf::cli::print_help(std::cout, "run", desc);
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
  if (o.ranks < 1 || o.ranks > 4096) throw Error("--ranks must be in [1, 4096]");
  if (o.ranks > 1) {
    if (!host::Dist::built_with_mpi())
      throw Error("--ranks " + std::to_string(o.ranks) + ": this stylerf was built without MPI (install libopenmpi-dev "
                  "and build again; stylerf --version says)");
    const auto words = launcher_words(o.mpirun);
    if (words.empty() || io::find_program(words.front()).empty())
      throw Error("--mpirun '" + o.mpirun + "': " + (words.empty() ? std::string("empty") : "'" + words.front() + "' is not on PATH (Debian: openmpi-bin)"));
  }
  if (o.frames < 2 || o.eval_views < 0 || o.table_frames < 8 || o.max_videos < 1 || o.holdout < 1)
    throw Error("--frames must be >= 2, --eval-views >= 0, --max-videos and --holdout-styles >= 1, --table-frames >= 8");
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

// Content rays a block the probe's frames took (its metrics' "supersample", what the recipe settled for this
// scene's map: "quincunx", "3x3" or "1"): a quincunx is the centre and ~1 shared corner ray.
int probe_rays_per_block(const std::string& metrics) {
  std::string name;
  try {
    std::ifstream in(metrics);
    name = nlohmann::json::parse(in).at("timing").at("supersample").get<std::string>();
  } catch (const std::exception& e) {
    throw Error(metrics + ": the frame probe's rays a block are unreadable (" + e.what() + ")");
  }
  try {
    const int n = model::parse_supersample(name);
    return n == model::kQuincunx ? 2 : n * n;
  } catch (const Error& e) {
    throw Error(metrics + ": the frame probe's " + e.what());
  }
}

// The cost of one frame of this scene on this machine (eval_budget.hpp): a one-step style checkpoint (the
// frame's cost does not depend on the weights' values) and 3 path frames of the first shown style.
// `spent` gains the probe's seconds; `style_fixed_s` gets the one-step run's, what a style stage costs
// besides its training minutes (start-up, loading, the first and last held-out checks, the checkpoint).
eval::FrameCost probe_frame_cost(PipelineSteps& steps, const RunOptions& o, const fs::path& out,
                                 const std::string& f_ck, const std::string& style, const std::string& key,
                                 double& spent, double& style_fixed_s) {
  const std::string p_ck = (out / "probe/style.ckpt").string(), p_dir = (out / "probe/frames").string();
  auto p = steps.run("probe_style",
                     args(o, "train-style", "--features", f_ck, "--styles", o.styles, "--holdout-styles",
                          std::to_string(o.holdout), "--recipe", o.recipe, "--iters", "1", "--warm-start", "0",
                          "--force", "-o", p_ck),
                     p_ck, key);
  spent += p.seconds;
  style_fixed_s = p.seconds;
  spent += steps.run("probe_frames",
            args(o, "stylize", "--ckpt", p_ck, "--style", style, "--views", "path", "--frames", "3", "--no-losses",
                 "--cache", "none", "-o", p_dir),
            p_dir + "/metrics.json", p.key).seconds;
  const std::string metrics = p_dir + "/metrics.json";
  eval::FrameCost c;
  double fps = 0;
  try {
    std::ifstream in(metrics);
    const auto j = nlohmann::json::parse(in);
    const auto& timing = j.at("timing");
    c.content = timing.at("content_render_s_per_view").get<double>();
    fps = timing.at("frames_per_s_after_first").get<double>();
    c.pixels = j.at("size").at(0).get<double>() * j.at("size").at(1).get<double>();
  } catch (const std::exception& e) {
    throw Error(metrics + ": the frame probe's timing is unreadable (" + e.what() + "); delete " +
                (out / "probe").string() + " to measure again");
  }
  if (!(c.content > 0) || !(fps > 0) || !std::isfinite(c.content) || !std::isfinite(fps))
    throw Error(metrics + ": the frame probe measured no time (content " + num(c.content) + " s, " + num(fps) +
                " frames/s); delete " + (out / "probe").string() + " to measure again");
  const double frame = 1.0 / fps;
  c.style2d = std::max(frame - c.content, 0.1 * frame);
  c.rays_per_block = probe_rays_per_block(metrics);
  return c;
}

// The seconds a render step took per view, its own timing in its metrics.json; 0 when it has none (a
// metrics file of an older build): the planner then counts such a view as a style2d.
double render_seconds_per_view(const std::string& metrics) {
  try {
    std::ifstream in(metrics);
    const double s = nlohmann::json::parse(in).at("timing").at("render_s_per_view").get<double>();
    return std::isfinite(s) && s > 0 ? s : 0.0;
  } catch (const std::exception&) {
    return 0.0;
  }
}

// The test views a render step wrote (its metrics.json lists them), or `fallback` when it cannot tell:
// eval style scores at most that many, whatever --eval-views asks (fern has 3).
int views_rendered(const std::string& metrics, int fallback) {
  try {
    std::ifstream in(metrics);
    const auto views = nlohmann::json::parse(in).at("views");
    return views.is_array() && !views.empty() ? int(views.size()) : fallback;
  } catch (const std::exception&) {
    return fallback;
  }
}

// Under --minutes: the style stage's minutes and the evaluation's counts, from the seconds spent so far
// and the measured frame. The evaluation may take what eval::eval_share_seconds allows (the style stage
// keeps ~15 minutes, or 35-65% of what is left); the counts shrink (fit_eval) to that share, and the style
// stage gets the rest, less its held-out checks and fixed seconds. Predictions carry eval::kEvalMargin.
// train-style's --minutes count its steps only; its held-out check every 100 steps comes on top, about as
// long as 5 steps (lego 1/4: 4.3-5.2 s a check at ~1.0 s a step; horns 1/8: 5.1-6.6 s at ~1.1 s), so the
// stage's wall time is its minutes x (1 + this) plus the fixed seconds the probe measured. Without it both
// 90-minute runs' style stages ended 2.4-2.7 min past their plan, and the videos paid for it.
constexpr double kHeldOutShare = 0.06;

struct EvalPlan {
  double style_minutes = 0;
  eval::EvalCounts counts;
  double predicted_eval_s = 0;  // with the margin
  std::string cuts;             // what fit_eval cut ("" when nothing)
};

// style_iters > 0: the style stage trains that many iterations (--stage-iters) whatever its planned minutes.
// report_spent_s: what the report has taken so far (the held-out renders and the probe).
EvalPlan plan_evaluation(const eval::FrameCost& c, const eval::EvalCounts& wanted, double minutes, double spent_s,
                         double report_spent_s, double nominal_style_min, double style_fixed_s, int style_iters) {
  const double left = minutes * 60.0 - spent_s, nominal_style = nominal_style_min * 60.0;
  EvalPlan plan;
  const double report_left = eval::kReportShare * minutes * 60.0 - report_spent_s;
  const double share = eval::eval_share_seconds(left, nominal_style, report_left);
  plan.counts = eval::fit_eval(c, wanted, share / eval::kEvalMargin);
  const double eval_s = eval::kEvalMargin * eval::eval_seconds(c, plan.counts);
  plan.predicted_eval_s = eval_s;
  plan.cuts = eval::describe_cuts(wanted, plan.counts);
  const double style_train_s = (left - eval_s - style_fixed_s) / (1 + kHeldOutShare);
  plan.style_minutes = std::max(0.25 * nominal_style, style_train_s) / 60.0;
  std::cout << "stylerf run: a frame here costs " << std::fixed << std::setprecision(2) << c.content
            << " s of content + " << c.style2d << " s a style (an RGB view " << c.rgb << " s; other 2D work "
            << eval::aux_unit(c) << " s a unit); evaluation predicted " << std::setprecision(1)
            << eval_s / 60.0 << " min, ";
  if (style_iters > 0)
    std::cout << "the style stage trains its " << style_iters << " iterations (--stage-iters)";
  else
    std::cout << "so the style stage gets " << plan.style_minutes << " min of training";
  if (!plan.cuts.empty()) std::cout << " (to fit: " << plan.cuts << ")";
  std::cout << std::endl;
  if (style_iters == 0 && style_train_s < 0.25 * nominal_style)
    std::cout << "stylerf run: warning: --minutes " << minutes << " is too short for this scene here; the run will "
              << "end about " << std::setprecision(0) << (0.25 * nominal_style - style_train_s) * (1 + kHeldOutShare) / 60.0
              << " min late" << std::endl;
  return plan;
}

// What a recipe sets, for the report: the feature profile and density shading it picks, and the style
// stage's whole configuration.
nlohmann::json recipe_settings(const std::string& recipe) {
  const train::Recipe r = train::parse_recipe(recipe);
  return {{"feature_profile", train::recipe_name(r)},
          {"density_shading", r == train::Recipe::Paper ? "per-sample" : "deferred"},
          {"style", train::style_recipe(r).to_json()}};
}

// Each training stage trains for its minutes or, under --stage-iters, its iterations.
std::vector<std::string> stage_length(const Budget& budget, int stage, double minutes) {
  return budget.iters.empty() ? std::vector<std::string>{"--minutes", num(minutes)}
                              : std::vector<std::string>{"--iters", std::to_string(budget.iters[size_t(stage)])};
}

void print_training_plan(const RunOptions& o, const Budget& budget) {
  if (budget.iters.empty())
    std::cout << "stylerf run: recipe " << o.recipe << "; training minutes: density " << std::fixed
              << std::setprecision(1) << budget.density << ", features " << budget.features << ", style "
              << budget.style << (o.stage_minutes.empty() ? " (replanned from a measured frame after the features)" : "")
              << std::endl;
  else
    std::cout << "stylerf run: recipe " << o.recipe << "; training iterations: density " << budget.iters[0]
              << ", features " << budget.iters[1] << ", style " << budget.iters[2]
              << (o.minutes_given ? "; the evaluation fitted to --minutes from a measured frame" : "") << std::endl;
}

// The run's checkpoints, and the steps that made the first two (their keys are what later steps depend on).
struct Checkpoints {
  std::string density, features, style;
  PipelineSteps::Result d, f;
};

// Stages 1 and 2 and their held-out renders; returns the seconds they took. The held-out renders come
// before the style stage, whose minutes are planned from the seconds spent so far (a skipped step counts
// its recorded seconds, so a resumed run plans the same minutes and the style step keeps its key).
double train_density_and_features(PipelineSteps& steps, const RunOptions& o, const Budget& budget,
                                  const fs::path& out, Checkpoints& ck) {
  std::vector<std::string> density = args(o, "train-density", "--scene", o.scene, "--recipe", o.recipe, "--force",
                                          "-o", ck.density);
  if (o.downsample > 0) density.insert(density.end(), {"--downsample", std::to_string(o.downsample)});
  for (const auto& a : stage_length(budget, 0, budget.density)) density.push_back(a);
  ck.d = steps.run("density", density, ck.density, folder_fingerprint(o.scene));
  std::vector<std::string> features = args(o, "train-features", "--density", ck.density, "--recipe", o.recipe,
                                           "--force", "-o", ck.features);
  for (const auto& a : stage_length(budget, 1, budget.features)) features.push_back(a);
  ck.f = steps.run("features", features, ck.features, ck.d.key);
  double spent = ck.d.seconds + ck.f.seconds;
  // The held-out renders feed only the report: the same few views as the style evaluation (all 200 of a
  // Blender scene at 800x800 took 8.5 minutes of a 90-minute run).
  const std::string views = std::to_string(o.eval_views);
  spent += steps.run("density_test",
                     args(o, "render", "--ckpt", ck.density, "--views", "test", "--max-views", views, "-o",
                          (out / "density_test").string()),
                     (out / "density_test/metrics.json").string(), ck.d.key).seconds;
  spent += steps.run("features_test",
                     args(o, "render", "--ckpt", ck.features, "--views", "test", "--max-views", views, "-o",
                          (out / "features_test").string()),
                     (out / "features_test/metrics.json").string(), ck.f.key).seconds;
  return spent;
}

// What the evaluation would do given all the time it wants.
eval::EvalCounts wanted_evaluation(const RunOptions& o, const fs::path& out, size_t shown,
                                   const train::StyleTrainConfig& recipe_cfg) {
  eval::EvalCounts counts;
  const int rendered = views_rendered((out / "features_test/metrics.json").string(), o.eval_views);
  counts.eval_views = o.eval_views == 0 ? rendered : std::min(o.eval_views, rendered);
  counts.holdout = o.holdout, counts.video_frames = o.frames;
  counts.shown = int(shown), counts.table_styles = int(shown), counts.table_frames = o.table_frames;
  counts.lpips_pair = eval::lpips_pair_units(eval::kDefaultLpipsNet);  // eval table's trunk, as run leaves it
  counts.structure_pair = eval::lpips_pair_units(eval::kDefaultLpipsNet);  // eval style's, the same
  // The recipe's decoder: vgg-adain-relu4 renders training views for the scene's relu4_1 statistics in
  // every evaluation step (horns 1/8: 6 views of ~10 s content each, a minute a step).
  if (model::map_decoder_for(recipe_cfg.style_decoder).renormalises_relu4())
    counts.scene_stats_views = model::SceneStyleStats::kDefaultViews;
  return counts;
}

// The style stage's minutes and the evaluation's counts: under --minutes (and under --stage-iters given
// --minutes as well) planned from a measured frame, otherwise the budget's and all that is wanted.
struct StylePlan {
  bool by_minutes = false;
  double style_minutes = 0;
  eval::FrameCost cost;
  eval::EvalCounts counts;
  nlohmann::json json;  // for summary.json
};

StylePlan plan_style_stage(PipelineSteps& steps, const RunOptions& o, const Budget& budget, const fs::path& out,
                           const Checkpoints& ck, const std::string& probe_style, const std::string& styles_fp,
                           const eval::EvalCounts& wanted, double& spent) {
  StylePlan sp;
  sp.by_minutes = o.stage_minutes.empty() && (budget.iters.empty() || o.minutes_given);
  sp.style_minutes = budget.style;
  sp.counts = wanted;
  if (!sp.by_minutes) return sp;
  const int style_iters = budget.iters.empty() ? 0 : budget.iters[2];
  double style_fixed_s = 0;
  sp.cost = probe_frame_cost(steps, o, out, ck.features, probe_style, ck.f.key + styles_fp, spent, style_fixed_s);
  sp.cost.rgb = render_seconds_per_view((out / "density_test/metrics.json").string());
  const double report_spent = spent - ck.d.seconds - ck.f.seconds;  // held-out renders and the probe
  const EvalPlan plan =
      plan_evaluation(sp.cost, wanted, o.minutes, spent, report_spent, budget.style, style_fixed_s, style_iters);
  sp.style_minutes = plan.style_minutes;
  sp.json = {{"frame_content_s", sp.cost.content},
             {"frame_style_s", sp.cost.style2d},
             {"frame_rays_per_block", sp.cost.rays_per_block},
             {"frame_rgb_s", sp.cost.rgb},
             {"frame_pixels", sp.cost.pixels},
             {"eval_views", wanted.eval_views},
             {"predicted_eval_s", plan.predicted_eval_s},
             {"style_minutes", sp.style_minutes},
             {"cuts", plan.cuts}};
  if (style_iters > 0) sp.json["style_iters"] = style_iters;
  sp.counts = plan.counts;
  return sp;
}

// Under a planned budget: the style stage and eval style may have run past their plan, so what is left of
// --minutes now sizes the videos, the mix sheet and the table.
void refit_after_style(const RunOptions& o, double spent_s, StylePlan& sp) {
  const double left = o.minutes * 60.0 - spent_s;
  eval::EvalCounts rest = sp.counts;
  rest.eval_views = 0, rest.holdout = 0;  // done
  const eval::EvalCounts fitted = eval::fit_eval(sp.cost, rest, left / eval::kEvalMargin);
  const std::string cuts = eval::describe_cuts(rest, fitted);
  if (!cuts.empty()) {
    std::cout << "stylerf run: " << std::fixed << std::setprecision(1) << left / 60.0
              << " min left for the videos, mix sheet and table: " << cuts << std::endl;
    sp.json["late_cuts"] = cuts;
  }
  sp.counts.video_frames = fitted.video_frames, sp.counts.shown = fitted.shown;
  sp.counts.table_frames = fitted.table_frames, sp.counts.table_styles = fitted.table_styles;
}

// The zero-shot videos of the first `counts.shown` styles, the mix sheet of the four corners and the
// consistency table of the first `counts.table_styles`.
void render_videos_mix_and_table(PipelineSteps& steps, const RunOptions& o, const fs::path& out,
                                 const Checkpoints& ck, const std::string& upstream,
                                 const std::vector<std::string>& shown, const std::vector<std::string>& corners,
                                 const eval::EvalCounts& counts) {
  const auto first = [&](int n) { return std::vector<std::string>(shown.begin(), shown.begin() + n); };
  std::vector<std::string> vid = args(o, "stylize", "--ckpt", ck.style, "--views", "path", "--frames",
                                      std::to_string(counts.video_frames), "--no-losses", "-o", (out / "videos").string());
  for (const auto& st : first(counts.shown)) vid.insert(vid.end(), {"--style", st});
  steps.run("videos", vid, (out / "videos/metrics.json").string(), upstream);
  steps.run("mix",
                      args(o, "stylize", "--ckpt", ck.style, "--views", "test", "--mix-grid",
                           corners[0] + "," + corners[1] + "," + corners[2] + "," + corners[3], "-o",
                           (out / "mix").string()),
                      (out / "mix/metrics.json").string(), upstream);
  std::vector<std::string> table = args(o, "eval", "table", "--scene-ckpts", ck.density + "," + ck.style, "--scored-frames",
                                        std::to_string(counts.table_frames), "-o", (out / "consistency").string(),
                                        "--styles");
  for (const auto& st : first(counts.table_styles)) table.push_back(st);
  steps.run("consistency", table, (out / "consistency/table.json").string(), upstream);
}

int run_pipeline(int argc, char** argv) {
  RunOptions o;
  int rc = 0;
  if (!parse_run_options(argc, argv, o, rc)) return rc;
  const Budget budget = split_budget(o.minutes, o.stage_minutes, o.stage_iters);
  const Shown picked = shown_styles(o);
  const std::vector<std::string>& shown = picked.styles;

  fs::create_directories(o.out);
  const fs::path out(o.out);
  const std::string self = fs::read_symlink("/proc/self/exe").string();
  PipelineSteps steps(o.out, self);
  if (o.ranks > 1) steps.split_over_ranks(o.ranks, launcher_words(o.mpirun));
  print_training_plan(o, budget);
  const std::string styles_fp = folder_fingerprint(o.styles);
  Checkpoints ck;
  ck.density = (out / "density.ckpt").string();
  ck.features = (out / "features.ckpt").string();
  ck.style = (out / "style.ckpt").string();
  double spent = train_density_and_features(steps, o, budget, out, ck);
  const train::StyleTrainConfig recipe_cfg = train::style_recipe(train::parse_recipe(o.recipe));
  StylePlan sp = plan_style_stage(steps, o, budget, out, ck, shown.front(), styles_fp,
                                  wanted_evaluation(o, out, shown.size(), recipe_cfg), spent);
  std::vector<std::string> style = args(o, "train-style", "--features", ck.features, "--styles", o.styles, "--holdout-styles",
                                        std::to_string(o.holdout), "--recipe", o.recipe, "--force", "-o", ck.style);
  for (const auto& a : stage_length(budget, 2, sp.style_minutes)) style.push_back(a);
  // The recipe's settings are in the key too: a later build whose recipe differs (say its content weight)
  // trains the style stage again instead of keeping a checkpoint of the old recipe.
  auto s = steps.run("style", style, ck.style, ck.f.key + styles_fp + recipe_cfg.to_json().dump());

  const std::string upstream = s.key + ck.d.key;
  const double eval_style_s =
      steps.run("style_eval",
                args(o, "eval", "style", "--ckpt", ck.style, "--max-views", std::to_string(sp.counts.eval_views),
                     "--max-styles", std::to_string(sp.counts.holdout), "-o", (out / "style_eval").string(), "--json",
                     (out / "style_eval.json").string()),
                (out / "style_eval.json").string(), upstream)
          .seconds;
  if (sp.by_minutes) refit_after_style(o, spent + s.seconds + eval_style_s, sp);
  render_videos_mix_and_table(steps, o, out, ck, upstream, shown, picked.corners, sp.counts);
  const std::vector<std::string> shown_now(shown.begin(), shown.begin() + sp.counts.shown);

  RunReportInput in;
  in.out = o.out;
  in.recipe = o.recipe;
  in.scene = o.scene;
  in.styles = o.styles;
  in.recipe_settings = recipe_settings(o.recipe);
  in.command_line = shell_command_line(argc, argv);
  in.device = device_record(o.device);
  in.build = build_record();
  in.minutes = !budget.iters.empty() ? 0.0 : o.stage_minutes.empty() ? o.minutes : budget.density + budget.features + budget.style;
  in.steps = steps.record();
  in.shown_styles = shown_now;
  in.plan = sp.json;
  in.corners = picked.corners;
  const RunSummary summary = write_run_report(in);
  print_run_summary(summary, std::cout);
  if (o.check && !summary.failures.empty()) {
    std::cout << "stylerf run --check: the result is degenerate:\n";
    for (const auto& why : summary.failures) std::cout << "  " << why << "\n";
    return 3;
  }
  return 0;
}

Register reg("run", run_pipeline);

}  // namespace
}  // namespace stylerf::cli
