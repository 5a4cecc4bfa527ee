// stylerf train-features --density CKPT --scene DIR [--profile fast|paper] [--minutes M | --iters N] -o CKPT:
// the feature stage (StyleRF stage 2) over the frozen geometry of a density checkpoint. Prints the profile,
// the targets (computed once, then read from the cache), progress lines (losses, patch PSNR, rays/s,
// ETA), and the decoded held-out PSNR at the end; checkpoints are atomic, with resume.
#include <boost/program_options.hpp>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <tuple>

#include "examples/stylerf/cli_checks.hpp"
#include "examples/stylerf/commands.hpp"
#include "host/error.hpp"
#include "host/runtime.hpp"
#include "lib/model/density_model.hpp"
#include "lib/scene/scene.hpp"
#include "lib/scene/scene_meta.hpp"
#include "lib/train/feature_trainer.hpp"
#include "lib/train/recipes.hpp"

namespace po = boost::program_options;
namespace fs = std::filesystem;

namespace {

using stylerf::host::Error;

int run_train_features(int argc, char** argv) {
  namespace train = stylerf::train;
  namespace model = stylerf::model;
  std::string density_path, dir, out, profile_name, recipe, device;
  int downsample = 0, iters = 0, log_every = 50, ckpt_every = 500, eval_views = 5, batch = 4096, patch = 256;
  double minutes = 0;
  float tv = -1, lr_grid = -1, lr_basis = -1, lr_decoder = -1;
  uint64_t seed = 0;
  bool resume = false, force = false, timing = false;
  po::options_description desc("stylerf train-features --density CKPT -o CKPT [options]");
  desc.add_options()("help,h", "show this help")("density", po::value(&density_path), "density-stage checkpoint")(
      "scene", po::value(&dir), "scene directory (default: the density checkpoint's)")(
      "downsample", po::value(&downsample), "image downsample factor (default: the density checkpoint's)")(
      "output,o", po::value(&out), "feature checkpoint to write")(
      "recipe", po::value(&recipe)->default_value("fast"),
      "fast: the fast profile | paper: the paper profile (the paper's stage 2); --profile overrides")(
      "profile", po::value(&profile_name),
      "fast (features at 1/4 resolution, AdaIN-initialised upsampling decoder) | paper (full resolution, "
      "PlainDecoder); default: the recipe's")(
      "iters", po::value(&iters), "iterations (ray and patch steps alternate; default 10000)")(
      "minutes", po::value(&minutes), "train for this much time; the lr decay is fitted to it (replaces --iters)")(
      "batch", po::value(&batch)->default_value(4096), "rays per ray step")(
      "patch", po::value(&patch)->default_value(256), "patch side in pixels (multiple of 8)")(
      "tv", po::value(&tv), "feature TV weight (default: 10 Blender, 80 LLFF)")(
      "lr-grid", po::value(&lr_grid), "feature grid learning rate (default 0.02)")(
      "lr-basis", po::value(&lr_basis), "basis matrix (and background feature) learning rate (default 1e-2)")(
      "lr-decoder", po::value(&lr_decoder), "decoder learning rate (default 2e-4 fast, 5e-4 paper)")(
      "seed", po::value(&seed)->default_value(0), "random seed")(
      "resume", po::bool_switch(&resume), "continue from the checkpoint at -o")(
      "force", po::bool_switch(&force), "overwrite an existing checkpoint at -o")(
      "log-every", po::value(&log_every)->default_value(50), "iterations between progress lines")(
      "ckpt-every", po::value(&ckpt_every)->default_value(500), "iterations between checkpoints")(
      "eval-views", po::value(&eval_views)->default_value(5), "held-out views for the final PSNR (0: all)")(
      "device", po::value(&device), "OpenCL device: index, cpu|gpu|accelerator, or part of a name")(
      "timing", po::bool_switch(&timing), "print per-kernel times at the end");
  po::variables_map vm;
  po::store(po::parse_command_line(argc, argv, desc), vm);
  po::notify(vm);
  if (vm.count("help") || out.empty() || (density_path.empty() && !resume)) {
    std::cout << desc;
    return vm.count("help") ? 0 : 2;
  }
  if (vm.count("iters") && iters < 1) throw Error("--iters must be >= 1 (got " + std::to_string(iters) + ")");
  if (vm.count("minutes") && !(minutes > 0 && std::isfinite(minutes)))
    throw Error("--minutes must be a positive number of minutes");
  if (minutes > 0 && iters > 0) throw Error("--minutes and --iters exclude each other");
  if (batch < 1 || log_every < 0 || ckpt_every < 0 || eval_views < 0)
    throw Error("--batch must be >= 1; --log-every, --ckpt-every and --eval-views >= 0");
  if (patch < 8 || patch % 8) throw Error("--patch must be a positive multiple of 8 (got " + std::to_string(patch) + ")");
  if (profile_name.empty()) profile_name = train::recipe_name(train::parse_recipe(recipe));  // a recipe's profile bears its name
  const auto profile = model::parse_decoder_profile(profile_name);
  stylerf::cli::check_checkpoint_output(out, resume, force);
  stylerf::cli::init_runtime(device, timing);

  std::unique_ptr<stylerf::io::Checkpoint> resumed;
  nlohmann::json dmeta_scene, density_meta;
  model::Geometry geometry;
  if (resume) {
    resumed = std::make_unique<stylerf::io::Checkpoint>(stylerf::io::load_checkpoint(out, "features"));
    const auto& tm = resumed->meta.at("trainer").at("config");
    if (tm.value("profile", "") != profile_name && vm.count("profile"))
      throw Error("--resume: checkpoint " + out + " was trained with --profile " + tm.value("profile", "") +
                  ", not " + profile_name);
    dmeta_scene = resumed->meta.value("scene", nlohmann::json::object());
    density_meta = resumed->meta.value("density", nlohmann::json::object());
  } else {
    const auto dck = stylerf::io::load_checkpoint(density_path, "density");
    geometry = model::load_model(dck).geo;
    dmeta_scene = dck.meta.value("scene", nlohmann::json::object());
    density_meta = {{"path", fs::absolute(density_path).string()},
                    {"iteration", dck.meta.value("trainer", nlohmann::json::object()).value("iteration", 0)}};
  }
  if (dir.empty()) dir = stylerf::scene::scene_dir_from_meta(dmeta_scene);
  auto lo = stylerf::scene::load_options_from_meta(dmeta_scene);
  if (downsample > 0) lo.downsample = downsample;
  lo.log = &std::cout;
  const auto scene = stylerf::scene::load_scene(dir, lo);
  stylerf::scene::check_same_scene(dmeta_scene, scene, lo.downsample, resume ? out : density_path);

  std::unique_ptr<train::FeatureTrainer> trainer;
  if (resume) {
    trainer = std::make_unique<train::FeatureTrainer>(scene, *resumed, &std::cout);
    std::cout << "resuming from " << out << " at iteration " << trainer->iteration() << "\n";
    if (iters > 0) trainer->set_total_iters(iters);
    if (trainer->done() && minutes <= 0)
      throw Error("--resume: checkpoint " + out + " is already at iteration " + std::to_string(trainer->iteration()) +
                  " of " + std::to_string(trainer->config().iters) + "; pass a larger --iters to continue");
  } else {
    auto cfg = train::default_feature_config(scene, profile);
    if (iters > 0) cfg.iters = iters;
    cfg.batch = batch;
    cfg.patch = patch;
    cfg.seed = seed;
    if (tv >= 0) cfg.tv = tv;
    for (auto [v, dst, flag] : {std::tuple{lr_grid, &cfg.lr_grid, "--lr-grid"}, std::tuple{lr_basis, &cfg.lr_basis, "--lr-basis"},
                                std::tuple{lr_decoder, &cfg.lr_decoder, "--lr-decoder"}}) {
      if (!vm.count(flag + 2)) continue;
      if (!(v > 0.0f) || !std::isfinite(v)) throw Error(std::string(flag) + " must be a positive number");
      *dst = v;
    }
    trainer = std::make_unique<train::FeatureTrainer>(scene, geometry, cfg, &std::cout);
  }
  const auto& cfg = trainer->config();
  auto& m = trainer->model();
  std::cout << "feature stage, " << model::decoder_profile_name(cfg.profile) << " profile: features rendered at 1/"
            << m.stride() << " resolution, decoder " << m.decoder.spec().describe() << "\n"
            << "  geometry (frozen): " << m.geo.describe() << "\n"
            << "  feature grid rank " << cfg.field.rank[0] << "/" << cfg.field.rank[1] << "/" << cfg.field.rank[2]
            << " -> basis " << m.field.head.channels() << "x" << cfg.field.channels << "; " << m.param_count() / 1e6
            << "M parameters\n"
            << "  ray steps of " << cfg.batch << " rays alternate with " << cfg.patch << " px patch steps; Adam lr grid "
            << cfg.lr_grid << ", basis " << cfg.lr_basis << ", decoder " << cfg.lr_decoder << ", TV " << cfg.tv
            << std::endl;

  train::FeatureRunOptions ro;
  ro.log = &std::cout;
  ro.log_every = log_every;
  ro.checkpoint = out;
  ro.checkpoint_every = ckpt_every;
  ro.time_budget_s = minutes * 60.0;
  ro.scene_meta = stylerf::scene::scene_meta(dir, lo, scene);
  ro.density_meta = density_meta;
  if (minutes > 0 && !resume) trainer->set_total_iters(1000000);  // refitted from the measured rate
  const auto sum = train::run_feature_training(*trainer, ro);
  std::cout << "trained " << sum.iterations << " iterations in " << std::fixed << std::setprecision(1) << sum.seconds
            << " s (" << std::setprecision(2) << sum.iterations / std::max(sum.seconds, 1e-9)
            << " it/s); checkpoint " << out << std::endl;
  if (!scene.test.empty()) {
    const auto t0 = std::chrono::steady_clock::now();
    const auto scores = train::evaluate_decoded(m, scene, eval_views, false);
    double p = 0;
    for (const auto& s : scores) p += s.psnr;
    std::cout << "decoded test PSNR " << std::setprecision(2) << p / std::max<size_t>(1, scores.size()) << " dB over "
              << scores.size() << " held-out views (" << std::setprecision(1)
              << std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() << " s)" << std::endl;
  }
  std::cout << "peak RSS " << std::fixed << std::setprecision(0) << stylerf::cli::peak_rss_mb() << " MB" << std::endl;
  if (timing) std::cout << stylerf::host::Runtime::instance().timing_report();
  return 0;
}

stylerf::cli::Register reg("train-features",
                           "feature stage: a VGG feature grid and decoder over a density checkpoint's geometry",
                           run_train_features);
}  // namespace
