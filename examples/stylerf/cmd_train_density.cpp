// stylerf train-density --scene DIR [--downsample N] [--iters N] ... -o CKPT: the density stage (TensoRF
// VM grids on RGB). Prints the scene and the effects switched on, the schedule, progress lines, and the
// held-out PSNR at the end; checkpoints are written atomically every --ckpt-every steps and at the end.
#include <boost/program_options.hpp>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <set>

#include "examples/stylerf/cli_checks.hpp"
#include "examples/stylerf/commands.hpp"
#include "examples/stylerf/help.hpp"
#include "host/dist.hpp"
#include "host/error.hpp"
#include "host/runtime.hpp"
#include "lib/scene/scene.hpp"
#include "lib/train/density_trainer.hpp"
#include "lib/train/recipes.hpp"

namespace po = boost::program_options;

namespace {

using stylerf::host::Error;

// "27000000", "300^3" -> voxel count. Bounded by 1024^3: beyond it the VM planes alone outgrow a
// device's largest allocation (TensoRF's largest default is 640^3, LLFF).
constexpr long long kMaxSide = 1024;
int64_t parse_voxels(const std::string& s, const std::string& flag) {
  try {
    size_t used = 0;
    const auto caret = s.find('^');
    if (caret != std::string::npos) {
      if (s.substr(caret) != "^3") throw std::invalid_argument(s);
      const long long side = std::stoll(s.substr(0, caret), &used);
      if (used != caret || side < 2) throw std::invalid_argument(s);
      if (side > kMaxSide) throw std::out_of_range(s);
      return side * side * side;
    }
    const long long v = std::stoll(s, &used);
    if (used != s.size() || v < 8) throw std::invalid_argument(s);
    if (v > kMaxSide * kMaxSide * kMaxSide) throw std::out_of_range(s);
    return v;
  } catch (const std::out_of_range&) {
    throw Error(flag + ": '" + s + "' is beyond the largest grid supported (" + std::to_string(kMaxSide) + "^3 voxels)");
  } catch (const std::exception&) {
    throw Error(flag + ": '" + s + "' is not a voxel count (e.g. 27000000 or 300^3)");
  }
}

std::array<int, 3> parse_rank(const std::string& s, const std::string& flag) {
  const auto v = stylerf::train::parse_int_list(s, flag);
  if (v.size() != 3 || v[0] < 1 || v[1] < 1 || v[2] < 1) throw Error(flag + ": expected three positive ranks, e.g. 16,4,4");
  return {v[0], v[1], v[2]};
}

namespace train = stylerf::train;
namespace cli = stylerf::cli;

// All of train-density's options, as parsed (`given`: the options set on the command line).
struct DensityArgs {
  std::string dir, out, ndc = "auto", act, final_voxels, init_voxels, upsample_at, mask_at, device, density_rank,
                    app_rank, shading, recipe;
  int downsample = 0, iters = 0, batch = 4096, batch_slices = 1, log_every = 100, ckpt_every = 1000, eval_views = 0;
  uint64_t seed = 0;
  float lr_grid = -1, lr_net = -1, ert = 1e-4f, backdrop_weight = -1, distortion_weight = -1;
  double minutes = 0;
  bool view_dep = false, resume = false, force = false, no_mask = false, timing = false;
  int64_t vfinal = 0, vinit = 0;  // parsed --final-voxels / --init-voxels (0: the default)
  std::set<std::string> given;
  bool has(const char* option) const { return given.count(option) > 0; }
};

// Parses argv into a. Returns -1 to go on, else the exit code (the help was shown).
int parse_density_args(int argc, char** argv, DensityArgs& a) {
  po::options_description desc("stylerf train-density --scene DIR -o CKPT [options]");
  desc.add_options()("help,h", "show this help")("scene", po::value(&a.dir), "scene directory (Blender, LLFF, COLMAP or nerfstudio format)")(
      "output,o", po::value(&a.out), "checkpoint file to write (safetensors)")(
      "downsample", po::value(&a.downsample),
      "image downsample factor (default: the paper's resolution, Blender 1 = 800x800, LLFF 4 = 1008x756; "
      "COLMAP and nerfstudio 1)")(
      "iters", po::value(&a.iters), "training iterations (default: TensoRF's, 30000 Blender, 25000 other formats)")(
      "minutes", po::value(&a.minutes), "train for this many minutes: the schedule (events, lr decay) is fitted to it "
                                        "from the measured step rate (replaces --iters)")(
      "batch", po::value(&a.batch)->default_value(4096), "rays per step")(
      "batch-slices", po::value(&a.batch_slices),
      "slices of each step's batch, rendered one by one and their gradients summed (default: one per MPI rank, 1 "
      "without MPI); the ranks share them round robin; a resumed run keeps its checkpoint's unless given")(
      "ndc", po::value(&a.ndc)->default_value("auto"), "NDC rays: auto (forward-facing LLFF), on, off")(
      "view-dependence", po::bool_switch(&a.view_dep), "view-dependent colour (off unless asked for)")(
      "density-activation", po::value(&a.act), "relu | softplus (default: TensoRF's config for the format)")(
      "final-voxels", po::value(&a.final_voxels), "final grid voxels (default: Blender 300^3; forward-facing captures 400^3, object captures 300^3, or TensoRF's 640^3 for both with --recipe paper)")(
      "init-voxels", po::value(&a.init_voxels), "initial grid voxels (default 128^3)")(
      "upsample-at", po::value(&a.upsample_at), "upsampling iterations (default 2000,3000,4000,5500)")(
      "mask-at", po::value(&a.mask_at), "alpha-mask update iterations (default 2000,4000; LLFF 2500)")(
      "no-alpha-mask", po::bool_switch(&a.no_mask), "never build the alpha mask")(
      "shading", po::value(&a.shading), "deferred (default: one MLP per ray on its mean feature) | per-sample "
                                        "(TensoRF: one MLP per kept sample)")(
      "recipe", po::value(&a.recipe)->default_value("fast"),
      "fast: deferred shading and a final grid of 400^3 for forward-facing captures, 300^3 for objects (each "
      "measured as good or better at equal time) | paper: per-sample "
      "shading and 640^3, TensoRF's (stage 1 of the paper); --shading and --final-voxels override")(
      "ert", po::value(&a.ert),
      "early ray termination: stop a ray once its transmittance is below this (0: off; default 1e-4, and off "
      "for NDC scenes, whose rays rarely turn opaque)")(
      "density-rank", po::value(&a.density_rank), "density ranks per mode (default: TensoRF's, 16,16,16 Blender, 16,4,4 other formats)")(
      "app-rank", po::value(&a.app_rank), "appearance ranks per mode (default: TensoRF's, 48,48,48 Blender, 48,12,12 other formats)")(
      "lr-grid", po::value(&a.lr_grid), "grid learning rate (default 0.02)")(
      "backdrop-weight", po::value(&a.backdrop_weight),
      "weight of the mean opacity of rays on backdrop pixels (scenes with a background: alpha, or a plain "
      "backdrop), which keeps a fog of the backdrop's colour out of the box (default 0.1; 0: off)")(
      "distortion-weight", po::value(&a.distortion_weight),
      "weight of the mean over a batch's rays of how far apart their weight lies along them (Mip-NeRF 360's "
      "distortion loss; distances over the box's diagonal): gathers a fog into surfaces (default: 0.01 for captures "
      "with a background shell, else 0: off)")(
      "lr-net", po::value(&a.lr_net), "basis + MLP learning rate (default 1e-3, TensoRF)")(
      "seed", po::value(&a.seed)->default_value(0), "random seed (init, rays, jitter)")(
      "resume", po::bool_switch(&a.resume), "continue from the checkpoint at -o (its iteration and optimiser state)")(
      "force", po::bool_switch(&a.force), "overwrite an existing checkpoint at -o")(
      "log-every", po::value(&a.log_every)->default_value(100), "iterations between progress lines")(
      "ckpt-every", po::value(&a.ckpt_every)->default_value(1000), "iterations between checkpoints")(
      "eval-views", po::value(&a.eval_views)->default_value(5),
      "held-out views for the final PSNR, evenly spaced (0: all; timed apart from training)")(
      "device", po::value(&a.device), stylerf::cli::kDeviceHelp)(
      "timing", po::bool_switch(&a.timing), "print per-kernel times at the end");
  stylerf::cli::apply_renamed_flags("train-density", argc, argv, {{"--profile", "--timing"}});
  po::variables_map vm;
  po::store(po::parse_command_line(argc, argv, desc), vm);
  po::notify(vm);
  for (const auto& kv : vm)
    if (!kv.second.defaulted()) a.given.insert(kv.first);
  if (vm.count("help") || argc <= 1) {
    stylerf::cli::print_help(std::cout, "train-density", desc);
    return vm.count("help") ? 0 : 2;
  }
  return -1;
}

// Every number is checked before anything loads: 0 or NaN never silently mean "the default".
void check_density_args(DensityArgs& a) {
  if (a.dir.empty()) throw Error("--scene DIR is required");
  if (a.has("downsample")) cli::check_int_range("--downsample", a.downsample, 1, 64);
  a.downsample = stylerf::scene::resolve_downsample(a.dir, a.downsample);
  if (a.has("iters")) cli::check_int_range("--iters", a.iters, 1, 10000000);
  if (a.has("minutes")) cli::check_range("--minutes", a.minutes, 0.01, 100000);
  if (a.minutes > 0 && (a.has("iters") || a.resume)) throw Error("--minutes goes without --iters and --resume");
  cli::check_int_range("--log-every", a.log_every, 0, 100000000);
  cli::check_int_range("--ckpt-every", a.ckpt_every, 0, 100000000);
  cli::check_int_range("--eval-views", a.eval_views, 0, 100000);
  if (a.has("ert")) cli::check_range("--ert", a.ert, 0.0, 0.5);
  if (a.shading.empty() && train::parse_recipe(a.recipe) == train::Recipe::Paper) a.shading = "per-sample";
  if (!a.shading.empty() && a.shading != "per-sample" && a.shading != "deferred")
    throw Error("--shading: unknown '" + a.shading + "' (per-sample, deferred)");
  {  // the config's own rules (DensityTrainConfig::validate), on the flags over the defaults
    train::DensityTrainConfig probe;
    probe.batch = a.batch;
    if (a.has("lr-grid")) probe.lr_grid = a.lr_grid;
    if (a.has("lr-net")) probe.lr_net = a.lr_net;
    if (a.has("backdrop-weight")) probe.backdrop_weight = a.backdrop_weight;
    if (a.has("distortion-weight")) probe.distortion_weight = a.distortion_weight;
    probe.validate();
  }
  if (a.resume)
    for (const char* o : {"final-voxels", "init-voxels", "upsample-at", "mask-at", "density-rank", "app-rank",
                          "lr-grid", "lr-net", "density-activation", "shading", "backdrop-weight",
                          "distortion-weight"})
      if (a.has(o))
        throw Error("--resume continues the checkpoint's own model and schedule; drop the model and schedule options");
  a.vfinal = a.final_voxels.empty() ? 0 : parse_voxels(a.final_voxels, "--final-voxels");
  a.vinit = a.init_voxels.empty() ? 0 : parse_voxels(a.init_voxels, "--init-voxels");
  if (a.vinit > 0 && a.vfinal > 0 && a.vinit > a.vfinal)
    throw Error("--init-voxels (" + a.init_voxels + ") must not exceed --final-voxels (" + a.final_voxels + ")");
  cli::check_checkpoint_output(a.out, a.resume, a.force);
}

// The trainer resumed from the checkpoint at -o (same scene; --iters only moves the horizon).
std::unique_ptr<train::DensityTrainer> resume_density_trainer(const DensityArgs& a, const stylerf::scene::Scene& scene) {
  const auto ck = stylerf::io::load_checkpoint(a.out, "density");
  if (ck.meta.contains("scene") && ck.meta["scene"].value("name", scene.name) != scene.name)
    throw Error("--resume: checkpoint " + a.out + " was trained on scene '" + ck.meta["scene"].value("name", "") +
                "', not '" + scene.name + "'");
  auto trainer = std::make_unique<train::DensityTrainer>(scene, ck);
  std::cout << "resuming from " << a.out << " at iteration " << trainer->iteration() << "\n";
  if (a.iters > 0 && a.iters <= trainer->iteration())
    throw Error("--resume --iters " + std::to_string(a.iters) + ": checkpoint " + a.out + " is already at iteration " +
                std::to_string(trainer->iteration()) + "; give a larger --iters to train further");
  if (a.iters > 0) {
    const int had = trainer->config().schedule.iters;
    if (a.iters != had)
      std::cout << "  --iters " << a.iters << " replaces the checkpoint's " << had << " (lr decay horizon)\n";
    trainer->set_total_iters(a.iters);
  }
  if (a.has("batch-slices")) trainer->set_batch_slices(a.batch_slices);
  return trainer;
}

// A new trainer: the scene format's defaults, then the options given.
std::unique_ptr<train::DensityTrainer> new_density_trainer(const DensityArgs& a, const stylerf::scene::Scene& scene) {
  auto cfg = train::default_density_config(scene, train::parse_recipe(a.recipe) == train::Recipe::Paper);
  // A run of N iterations gets the schedule a budget of N iterations gets (Schedule::fitted): TensoRF's
  // events (upsampling from 2000, masks) would otherwise never fire in a short run.
  if (a.iters > 0) cfg.schedule = cfg.schedule.fitted(a.iters);
  cfg.batch = a.batch;
  cfg.seed = a.seed;
  cfg.batch_slices = a.has("batch-slices") ? a.batch_slices : stylerf::host::Dist::world().size();
  if (!a.act.empty()) cfg.model.act = stylerf::field::parse_density_activation(a.act);
  if (a.vfinal > 0) cfg.schedule.voxels_final = a.vfinal;
  if (a.vinit > 0) cfg.schedule.voxels_init = a.vinit;
  if (cfg.schedule.voxels_init > cfg.schedule.voxels_final)
    throw Error("--init-voxels " + std::to_string(cfg.schedule.voxels_init) + " exceeds the final grid's " +
                std::to_string(cfg.schedule.voxels_final) + " voxels; pass a larger --final-voxels");
  if (a.has("upsample-at")) cfg.schedule.upsample_at = train::parse_int_list(a.upsample_at, "--upsample-at");
  if (a.has("mask-at")) cfg.schedule.mask_at = train::parse_int_list(a.mask_at, "--mask-at");
  if (a.no_mask) cfg.alpha_mask = false;
  if (!a.density_rank.empty()) cfg.model.density_rank = parse_rank(a.density_rank, "--density-rank");
  if (!a.app_rank.empty()) cfg.model.app_rank = parse_rank(a.app_rank, "--app-rank");
  if (a.has("lr-grid")) cfg.lr_grid = a.lr_grid;
  if (a.has("lr-net")) cfg.lr_net = a.lr_net;
  if (a.has("backdrop-weight")) cfg.backdrop_weight = a.backdrop_weight;
  if (a.has("distortion-weight")) cfg.distortion_weight = a.distortion_weight;
  if (!a.shading.empty()) cfg.model.deferred_shading = a.shading == "deferred";
  return std::make_unique<train::DensityTrainer>(scene, cfg);
}

void print_density_setup(train::DensityTrainer& trainer, const stylerf::scene::Scene& scene) {
  const auto& cfg = trainer.config();
  const float ert = trainer.model().geo.ert_threshold;
  std::cout << "density stage: " << trainer.model().describe() << "\n"
            << "  activation " << (cfg.model.act == stylerf::field::DensityActivation::Relu ? "relu" : "softplus")
            << ", view dependence " << (cfg.model.view_dependent ? "on" : "off") << ", shading "
            << (cfg.model.deferred_shading ? "deferred" : "per sample") << ", early termination "
            << (ert > 0 ? "below " + std::to_string(ert) : std::string("off")) << ", background "
            << (scene.effects.background ? "colour" : trainer.model().geo.shell.on() ? "shell" : "off") << ", NDC " << (scene.effects.ndc ? "on" : "off") << "\n"
            << "  " << cfg.schedule.describe() << "\n"
            << "  batch " << cfg.batch
            << (cfg.batch_slices > 1 ? " in " + std::to_string(cfg.batch_slices) + " slices" : std::string())
            << (stylerf::host::Dist::world().size() > 1
                    ? " dealt round robin over " + std::to_string(stylerf::host::Dist::world().size()) + " ranks"
                    : std::string())
            << ", Adam lr grid " << cfg.lr_grid << " / network " << cfg.lr_net
            << " betas (" << cfg.beta1 << ", " << cfg.beta2 << "), L1 " << cfg.l1_initial << " -> " << cfg.l1_rest
            << ", TV density " << cfg.tv_density << " app " << cfg.tv_app;
  if (cfg.distortion_weight > 0) std::cout << ", distortion x" << cfg.distortion_weight;
  if (trainer.backdrop_share() > 0)
    std::cout << ", backdrop opacity x" << cfg.backdrop_weight << " on " << std::setprecision(1) << std::fixed
              << 100.0 * trainer.backdrop_share() << "% of the training pixels" << std::defaultfloat
              << std::setprecision(6);
  std::cout << std::endl;
}

// Held-out PSNR, timed apart from training.
void report_density_psnr(train::DensityTrainer& trainer, const stylerf::scene::Scene& scene, int eval_views) {
  if (scene.test.empty()) return;
  const auto t_eval = std::chrono::steady_clock::now();
  const auto scores = train::evaluate_views(trainer.model(), scene, eval_views, false);
  std::cout << "test PSNR " << std::setprecision(2) << train::mean_psnr(scores) << " dB over " << scores.size()
            << " held-out views (evaluation " << std::setprecision(1)
            << std::chrono::duration<double>(std::chrono::steady_clock::now() - t_eval).count()
            << " s, beside the training time; --eval-views 0 for all " << scene.test.size() << ")" << std::endl;
  if (const double b = train::mean_backdrop_acc(scores); b >= 0)
    std::cout << "held-out backdrop opacity " << std::setprecision(4) << b
              << " (mean over the held-out views' backdrop pixels: fog there is painted by the stylised stages)"
              << std::endl;
}

int run_train_density(int argc, char** argv) {
  DensityArgs a;
  if (const int code = parse_density_args(argc, argv, a); code >= 0) return code;
  check_density_args(a);
  stylerf::cli::init_runtime(a.device, a.timing);

  stylerf::scene::LoadOptions lo;
  lo.downsample = a.downsample;
  lo.ndc = stylerf::scene::parse_switch(a.ndc, "--ndc");
  lo.view_dependence = a.view_dep;
  lo.log = &std::cout;
  const auto scene = stylerf::scene::load_scene(a.dir, lo);
  auto trainer = a.resume ? resume_density_trainer(a, scene) : new_density_trainer(a, scene);
  if (a.has("ert")) trainer->model().geo.ert_threshold = a.ert;
  print_density_setup(*trainer, scene);

  train::RunOptions ro;
  ro.log = &std::cout;
  ro.log_every = a.log_every;
  ro.checkpoint = a.out;
  ro.checkpoint_every = a.ckpt_every;
  ro.time_budget_s = a.minutes * 60.0;
  ro.fit_schedule_to_budget = a.minutes > 0;
  ro.scene_meta = stylerf::scene::scene_meta(a.dir, lo, scene);
  const auto sum = train::run_density_training(*trainer, ro);
  std::cout << "trained " << sum.iterations << " iterations in " << std::fixed << std::setprecision(1) << sum.seconds
            << " s (" << std::setprecision(2) << sum.iterations / std::max(sum.seconds, 1e-9) << " it/s); checkpoint "
            << a.out << "\n";
  if (trainer->sync().steps > 0)
    std::cout << "gradients summed over " << train::sync_summary(trainer->sync(), stylerf::host::Dist::world().size())
              << "\n";
  report_density_psnr(*trainer, scene, a.eval_views);
  std::cout << "peak RSS " << std::fixed << std::setprecision(0) << stylerf::cli::peak_rss_mb() << " MB" << std::endl;
  if (a.timing) std::cout << stylerf::host::Runtime::instance().timing_report();
  return 0;
}

stylerf::cli::Register reg("train-density", run_train_density);
}  // namespace
