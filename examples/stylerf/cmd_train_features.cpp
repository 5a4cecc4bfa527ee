// stylerf train-features --density CKPT --scene DIR [--profile fast|paper] [--minutes M | --iters N] -o CKPT:
// the feature stage (StyleRF stage 2) over the frozen geometry of a density checkpoint. Prints the profile,
// the targets (computed once, then read from the cache), progress lines (losses, patch PSNR, rays/s,
// ETA), and the decoded held-out PSNR at the end; checkpoints are atomic, with resume.
#include <boost/program_options.hpp>
#include <cmath>
#include <iomanip>
#include <iostream>
#include <chrono>
#include <memory>
#include <set>
#include <tuple>

#include "examples/stylerf/cli_checks.hpp"
#include "examples/stylerf/commands.hpp"
#include "examples/stylerf/help.hpp"
#include "host/dist.hpp"
#include "host/error.hpp"
#include "host/runtime.hpp"
#include "lib/model/density_model.hpp"
#include "lib/scene/scene.hpp"
#include "lib/scene/scene_meta.hpp"
#include "lib/train/feature_trainer.hpp"
#include "lib/train/recipes.hpp"

namespace po = boost::program_options;

namespace {

using stylerf::host::Error;

namespace train = stylerf::train;
namespace model = stylerf::model;

// All of train-features' options, as parsed (`given`: the options set on the command line).
struct FeatureArgs {
  std::string density_path, dir, out, profile_name, recipe, device;
  int downsample = 0, iters = 0, log_every = 50, ckpt_every = 500, eval_views = 5, batch = 4096, patch = 256,
      patches_per_step = 1;
  double minutes = 0;
  float tv = -1, content_weight = -1, lr_grid = -1, lr_basis = -1, lr_decoder = -1;
  uint64_t seed = 0;
  bool resume = false, force = false, timing = false;
  std::set<std::string> given;
};

// Parses argv into a. Returns -1 to go on, else the exit code (the help was shown).
int parse_feature_args(int argc, char** argv, FeatureArgs& a) {
  po::options_description desc("stylerf train-features --density CKPT -o CKPT [options]");
  desc.add_options()("help,h", "show this help")("density", po::value(&a.density_path), "density-stage checkpoint")(
      "scene", po::value(&a.dir), "scene directory (default: the density checkpoint's)")(
      "downsample", po::value(&a.downsample), "image downsample factor (default: the density checkpoint's)")(
      "output,o", po::value(&a.out), "feature checkpoint to write")(
      "recipe", po::value(&a.recipe)->default_value("fast"),
      "fast: the fast profile | paper: the paper profile (the paper's stage 2); --profile overrides")(
      "profile", po::value(&a.profile_name),
      "fast (features at 1/4 resolution, AdaIN-initialised upsampling decoder) | paper (full resolution, "
      "PlainDecoder); default: the recipe's")(
      "iters", po::value(&a.iters), "iterations (ray and patch steps alternate; default 10000)")(
      "minutes", po::value(&a.minutes), "train for this many minutes; the lr decay is fitted to it (replaces --iters)")(
      "batch", po::value(&a.batch)->default_value(4096), "rays per ray step")(
      "patch", po::value(&a.patch)->default_value(256), "patch side in pixels (multiple of 8)")(
      "tv", po::value(&a.tv), "feature TV weight (default: 10 Blender, 80 LLFF)")(
      "content-weight", po::value(&a.content_weight),
      "patch steps' (relu3_1 + relu4_1 MSE) weight beside the pixel MSE; 0: pixels alone, no VGG pass "
      "(default: 0 fast profile, 0.1 paper)")(
      "lr-grid", po::value(&a.lr_grid), "feature grid learning rate (default 0.02)")(
      "lr-basis", po::value(&a.lr_basis), "basis matrix (and background feature) learning rate (default 1e-2)")(
      "lr-decoder", po::value(&a.lr_decoder), "decoder learning rate (default 2e-4 fast, 5e-4 paper)")(
      "patches-per-step", po::value(&a.patches_per_step),
      "patches whose gradients a patch step averages (default: one per MPI rank, 1 without MPI); the ranks share "
      "them round robin and slice each ray step's batch; a resumed run keeps its checkpoint's unless given")(
      "seed", po::value(&a.seed)->default_value(0), "random seed")(
      "resume", po::bool_switch(&a.resume), "continue from the checkpoint at -o")(
      "force", po::bool_switch(&a.force), "overwrite an existing checkpoint at -o")(
      "log-every", po::value(&a.log_every)->default_value(50), "iterations between progress lines")(
      "ckpt-every", po::value(&a.ckpt_every)->default_value(500), "iterations between checkpoints")(
      "eval-views", po::value(&a.eval_views)->default_value(5), "held-out views for the final PSNR (0: all)")(
      "device", po::value(&a.device), stylerf::cli::kDeviceHelp)(
      "timing", po::bool_switch(&a.timing), "print per-kernel times at the end");
  po::variables_map vm;
  po::store(po::parse_command_line(argc, argv, desc), vm);
  po::notify(vm);
  for (const auto& kv : vm)
    if (!kv.second.defaulted()) a.given.insert(kv.first);
  if (vm.count("help") || a.out.empty() || (a.density_path.empty() && !a.resume)) {
    stylerf::cli::print_help(std::cout, "train-features", desc);
    return vm.count("help") ? 0 : 2;
  }
  return -1;
}

// The flags given, over a profile's config.
void apply_feature_flags(const FeatureArgs& a, train::FeatureTrainConfig& cfg) {
  if (a.given.count("iters")) cfg.iters = a.iters;
  cfg.batch = a.batch;
  cfg.patch = a.patch;
  cfg.seed = a.seed;
  cfg.patches_per_step = a.given.count("patches-per-step") ? a.patches_per_step : stylerf::host::Dist::world().size();
  if (a.given.count("tv")) cfg.tv = a.tv;
  if (a.given.count("content-weight")) cfg.content_weight = a.content_weight;
  if (a.given.count("lr-grid")) cfg.lr_grid = a.lr_grid;
  if (a.given.count("lr-basis")) cfg.lr_basis = a.lr_basis;
  if (a.given.count("lr-decoder")) cfg.lr_decoder = a.lr_decoder;
}

// Every option checked before anything is loaded (the run's own here, the config's by the library's rules,
// FeatureTrainConfig::validate); the profile a recipe names when --profile is absent.
model::DecoderProfile check_feature_args(FeatureArgs& a) {
  if (a.given.count("minutes") && !(a.minutes > 0 && std::isfinite(a.minutes)))
    throw Error("--minutes must be a positive number of minutes");
  if (a.minutes > 0 && a.given.count("iters")) throw Error("--minutes and --iters exclude each other");
  if (a.log_every < 0 || a.ckpt_every < 0 || a.eval_views < 0)
    throw Error("--log-every, --ckpt-every and --eval-views must be >= 0");
  if (a.profile_name.empty())
    a.profile_name = train::recipe_name(train::parse_recipe(a.recipe));  // a recipe's profile bears its name
  const auto profile = model::parse_decoder_profile(a.profile_name);
  if (!a.resume) {
    train::FeatureTrainConfig probe;
    apply_feature_flags(a, probe);
    probe.validate();
  }
  stylerf::cli::check_checkpoint_output(a.out, a.resume, a.force);
  return profile;
}

// Where training starts from: the checkpoint at -o (--resume) or the density checkpoint's geometry, with
// the scene metadata both carry.
struct FeatureSource {
  std::unique_ptr<stylerf::io::Checkpoint> resumed;
  model::Geometry geometry;
  nlohmann::json scene_meta, density_meta;
};

FeatureSource open_feature_source(const FeatureArgs& a) {
  FeatureSource src;
  if (a.resume) {
    src.resumed = std::make_unique<stylerf::io::Checkpoint>(stylerf::io::load_checkpoint(a.out, "features"));
    const auto& tm = src.resumed->meta.at("trainer").at("config");
    if (tm.value("profile", "") != a.profile_name && a.given.count("profile"))
      throw Error("--resume: checkpoint " + a.out + " was trained with --profile " + tm.value("profile", "") +
                  ", not " + a.profile_name);
    src.scene_meta = src.resumed->meta.value("scene", nlohmann::json::object());
    src.density_meta = src.resumed->meta.value("density", nlohmann::json::object());
  } else {
    const auto dck = stylerf::io::load_checkpoint(a.density_path, "density");
    src.geometry = model::load_model(dck).geo;
    src.scene_meta = dck.meta.value("scene", nlohmann::json::object());
    src.density_meta = train::density_source_meta(a.density_path, dck);
  }
  return src;
}

// The trainer: resumed from its checkpoint, or new from the profile's defaults and the options given.
std::unique_ptr<train::FeatureTrainer> make_feature_trainer(const FeatureArgs& a, model::DecoderProfile profile,
                                                           const stylerf::scene::Scene& scene, FeatureSource& src) {
  if (a.resume) {
    auto trainer = std::make_unique<train::FeatureTrainer>(scene, *src.resumed, &std::cout);
    std::cout << "resuming from " << a.out << " at iteration " << trainer->iteration() << "\n";
    if (a.given.count("iters")) {
      train::FeatureTrainConfig longer = trainer->config();
      longer.iters = a.iters;
      longer.validate();
      trainer->set_total_iters(a.iters);
    }
    if (a.given.count("patches-per-step")) trainer->set_patches_per_step(a.patches_per_step);
    if (trainer->done() && a.minutes <= 0)
      throw Error("--resume: checkpoint " + a.out + " is already at iteration " + std::to_string(trainer->iteration()) +
                  " of " + std::to_string(trainer->config().iters) + "; pass a larger --iters to continue");
    return trainer;
  }
  auto cfg = train::default_feature_config(scene, profile);
  apply_feature_flags(a, cfg);
  return std::make_unique<train::FeatureTrainer>(scene, src.geometry, cfg, &std::cout);
}

void print_feature_setup(train::FeatureTrainer& trainer) {
  const auto& cfg = trainer.config();
  auto& m = trainer.model();
  std::cout << "feature stage, " << model::decoder_profile_name(cfg.profile) << " profile: features rendered at 1/"
            << m.stride() << " resolution, decoder " << m.decoder.spec().describe() << "\n"
            << "  geometry (frozen): " << m.geo.describe() << "\n"
            << "  feature grid rank " << cfg.field.rank[0] << "/" << cfg.field.rank[1] << "/" << cfg.field.rank[2]
            << " -> basis " << m.field.head.channels() << "x" << cfg.field.channels << "; " << m.param_count() / 1e6
            << "M parameters\n"
            << "  ray steps of " << cfg.batch << " rays alternate with " << cfg.patch << " px patch steps ("
            << cfg.patches_per_step << (cfg.patches_per_step == 1 ? " patch" : " patches") << " a step"
            << (stylerf::host::Dist::world().size() > 1
                    ? ", dealt round robin over " + std::to_string(stylerf::host::Dist::world().size()) +
                          " ranks, which slice each ray batch"
                    : std::string())
            << "); Adam lr grid "
            << cfg.lr_grid << ", basis " << cfg.lr_basis << ", decoder " << cfg.lr_decoder << ", TV " << cfg.tv
            << std::endl;
}

// The decoded maps' PSNR on held-out views, timed apart from training.
void report_decoded_psnr(train::FeatureTrainer& trainer, const stylerf::scene::Scene& scene, int eval_views) {
  if (scene.test.empty()) return;
  const auto t0 = std::chrono::steady_clock::now();
  const auto scores = train::evaluate_decoded(trainer.model(), scene, eval_views, false);
  double p = 0;
  for (const auto& s : scores) p += s.psnr;
  std::cout << "decoded test PSNR " << std::setprecision(2) << p / std::max<size_t>(1, scores.size()) << " dB over "
            << scores.size() << " held-out views (" << std::setprecision(1)
            << std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() << " s)" << std::endl;
}

int run_train_features(int argc, char** argv) {
  FeatureArgs a;
  if (const int code = parse_feature_args(argc, argv, a); code >= 0) return code;
  const auto profile = check_feature_args(a);
  stylerf::cli::init_runtime(a.device, a.timing);

  FeatureSource src = open_feature_source(a);
  stylerf::scene::SceneOverrides o;
  o.dir = a.dir;
  o.downsample = a.downsample;
  o.log = &std::cout;
  const auto opened = stylerf::scene::open_scene_for(src.scene_meta, a.resume ? a.out : a.density_path, o);
  const stylerf::scene::Scene& scene = opened.scene;
  auto trainer = make_feature_trainer(a, profile, scene, src);
  print_feature_setup(*trainer);

  train::FeatureRunOptions ro;
  ro.log = &std::cout;
  ro.log_every = a.log_every;
  ro.checkpoint = a.out;
  ro.checkpoint_every = a.ckpt_every;
  ro.time_budget_s = a.minutes * 60.0;
  ro.scene_meta = stylerf::scene::scene_meta(opened.dir, opened.options, scene);
  ro.density_meta = src.density_meta;
  if (a.minutes > 0 && !a.resume) trainer->set_total_iters(1000000);  // refitted from the measured rate
  const auto sum = train::run_feature_training(*trainer, ro);
  std::cout << "trained " << sum.iterations << " iterations in " << std::fixed << std::setprecision(1) << sum.seconds
            << " s (" << std::setprecision(2) << sum.iterations / std::max(sum.seconds, 1e-9)
            << " it/s); checkpoint " << a.out << std::endl;
  if (trainer->sync().steps > 0)
    std::cout << "gradients summed over " << train::sync_summary(trainer->sync(), stylerf::host::Dist::world().size())
              << std::endl;
  report_decoded_psnr(*trainer, scene, a.eval_views);
  std::cout << "peak RSS " << std::fixed << std::setprecision(0) << stylerf::cli::peak_rss_mb() << " MB" << std::endl;
  if (a.timing) std::cout << stylerf::host::Runtime::instance().timing_report();
  return 0;
}

stylerf::cli::Register reg("train-features", run_train_features);
}  // namespace
