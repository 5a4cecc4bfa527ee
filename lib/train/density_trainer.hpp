// The density stage (TensoRF on RGB): the training loop, its configuration with TensoRF's defaults, and
// checkpoints with the optimiser state for --resume.
//
// One step: 4096 random rays over every training pixel -> render_rays (jittered marching) -> loss =
// MSE(rgb, target) + L1 * density-grid L1 + TV terms (+ the backdrop term where the scene has a background:
// backdrop_weight below) -> render_rays_backward -> Adam (betas 0.9, 0.99) with
// grid lr 0.02 and network lr 1e-3 (TensoRF's lr_basis; docs/design.md quotes 1e-4 for StyleRF's later network
// stages, the density stage follows TensoRF), both scaled by Schedule::lr_scale.
// Events after step k: alpha-mask update (the first one also shrinks the box to the occupied region,
// carrying the Adam moments by the same crop, and switches L1 to its "rest" weight), then grid upsampling
// (TensoRF rebuilds its optimiser there: the moments and Adam's step count restart from zero; with
// reset_optimizer_on_upsample off the moments are resampled with the grid instead).
// A non-finite loss, or a NaN/inf in any parameter (checked every finite_check_every steps and before each
// checkpoint), stops training with an Error naming the iteration (and the parameter).
#pragma once
#include <functional>
#include <memory>
#include <iosfwd>
#include <string>
#include <vector>

#include "lib/scene/rays.hpp"
#include "lib/scene/scene.hpp"
#include "lib/scene/scene_meta.hpp"
#include "lib/model/density_model.hpp"
#include "lib/nn/adam.hpp"
#include "lib/train/budget.hpp"
#include "lib/train/schedule.hpp"
#include "lib/train/data_parallel.hpp"
#include "lib/train/training_loop.hpp"

namespace stylerf::train {

using model::DensityModel;
using model::DensityModelConfig;
using host::Tensor;

inline constexpr float kDefaultBackdropWeight = 0.1f;
// The distortion term's weight for captures with a background shell (default_density_config).
inline constexpr float kShellDistortionWeight = 0.01f;

struct DensityTrainConfig {
  DensityModelConfig model;
  Schedule schedule;
  int batch = 4096;
  float lr_grid = 0.02f, lr_net = 1e-3f, beta1 = 0.9f, beta2 = 0.99f;
  float l1_initial = 8e-5f, l1_rest = 4e-5f;  // TensoRF Blender; LLFF 0
  float tv_density = 0.0f, tv_app = 0.0f;     // TensoRF LLFF: 1.0 and 1.0 (times its 1e-2 and TVLoss's 2)
  bool alpha_mask = true;
  // Weight of the backdrop term: the mean over a batch's rays of the opacity of those whose pixel shows
  // the scene's backdrop (scene::backdrop_pixels; scenes with a background only). Without it a fog of the
  // backdrop's colour costs nothing, and the stylised stages paint it (docs/results.md, "backdrop").
  float backdrop_weight = kDefaultBackdropWeight;
  // Weight of the distortion term (render/distortion.hpp): the mean over a batch's rays of how far apart
  // their weight lies along them, distances in units of the box's diagonal. 0: off; default_density_config
  // turns it on for captures with a background shell.
  float distortion_weight = 0.0f;
  bool reset_optimizer_on_upsample = true;
  uint64_t seed = 0;
  // Slices of a step's batch, each rendered and differentiated on its own and their gradients summed; over
  // MPI ranks they are dealt round robin (lib/train/data_parallel.hpp), and 1 rank taking N slices takes
  // the step N ranks take.
  int batch_slices = 1;
  // Every this many steps (and before every checkpoint) the parameters are checked for NaN/inf: the
  // compositing treats a NaN density as empty and the sigmoid head maps a NaN to a colour, so a corrupted
  // grid need not show in the loss. About 6 ms per check for a 300^3 grid. Not stored in checkpoints.
  int finite_check_every = 25;

  // Every field's rule, in one place (the schedule's too): a host::SettingError naming the field.
  void validate() const;
  nlohmann::json to_json() const;
  static DensityTrainConfig from_json(const nlohmann::json& j);
};

// TensoRF's configs: lego.txt for Blender-format scenes (ours from make-scene included), flower.txt
// (forward-facing LLFF) for LLFF scenes: ranks, activation, final voxels, mask iterations, L1/TV weights.
// tensorf_grid = false (the fast recipe, the default) gives scenes with NDC rays (forward-facing captures) a final grid of
// kFastLlffFinalSide^3 and other captures (objects) kFastObjectFinalSide^3 instead of flower.txt's 640^3
// (each measured as good or better at equal time, and cheaper: density_trainer.cpp).
DensityTrainConfig default_density_config(const scene::Scene& scene, bool tensorf_grid = false);
inline constexpr int kFastLlffFinalSide = 400;
inline constexpr int kFastObjectFinalSide = 300;

struct StepStats {
  int iteration = 0;         // completed steps
  double mse = 0, psnr = 0;  // of the batch
  double reg = -1;           // regulariser value (computed only when asked for; -1 otherwise)
  int backdrop_rays = 0;     // rays of the batch on backdrop pixels, and their mean opacity
  double backdrop_acc = 0;
  double distortion = 0;     // the distortion term of the batch (weighted; 0 when off)
  int64_t samples = 0, kept = 0;
  double seconds = 0;        // wall time of the step (events included)
  std::vector<std::string> events;  // "alpha mask ...", "upsampled to ..."
};

class DensityTrainer {
 public:
  DensityTrainer(const scene::Scene& scene, const DensityTrainConfig& cfg);
  // Restores model, optimiser state and iteration from a checkpoint written by save().
  DensityTrainer(const scene::Scene& scene, const io::Checkpoint& ck);

  // One step; with_reg also evaluates the regulariser value for reporting.
  StepStats step(bool with_reg = false);
  void set_batch_slices(int n) {
    DensityTrainConfig c = cfg_;
    c.batch_slices = n;
    c.validate();
    cfg_.batch_slices = n;
  }
  int iteration() const { return iteration_; }
  // The gradient sums over MPI ranks so far (lib/train/data_parallel.hpp).
  const SyncTotals& sync() const { return sync_; }
  bool done() const { return iteration_ >= cfg_.schedule.iters; }
  const DensityModel& model() const { return model_; }
  DensityModel& model() { return model_; }
  const DensityTrainConfig& config() const { return cfg_; }
  // The share of training pixels the backdrop term watches (0: the term is off).
  double backdrop_share() const;
  // Changes the run's length (a resumed run extended or shortened; the lr decay horizon moves with it).
  void set_total_iters(int iters) {
    cfg_.schedule.iters = iters;
    cfg_.schedule.validate();
  }
  // Re-sizes the rest of the run to `total_iters` steps: the schedule the trainer was built with, fitted
  // to that length (Schedule::fitted); events that already fired keep their iterations, later ones move
  // (never to a step already taken), and events not yet fired that would land in the last 10% of the run
  // are dropped (the final grid is then the last kept upsample's). Used by time-budgeted runs as the step
  // rate becomes known.
  void refit_schedule(int total_iters);
  // `scene_meta` (how to reload the scene) is stored beside the model and optimiser state.
  void save(const std::string& path, const nlohmann::json& scene_meta);

 private:
  void init_optimizer();
  // Throws an Error naming the first parameter holding a NaN or an infinity, and `when`.
  void check_finite(const std::string& when);
  // Runs `change` (a crop or an upsampling of both grids, described by c) and carries the grids' Adam
  // moments through the same crop/resampling.
  void carry_moments(const model::GridCrop& c, const std::function<void()>& change);
  void on_step_done(StepStats& st);
  // Rays [lo, lo + n) of the step's batch: their data terms' gradients (means over the whole batch) into
  // the params; sums += their mse share, samples, kept samples, backdrop opacity and backdrop rays.
  void slice_terms(const scene::Rays& batch, int64_t lo, int64_t n, int k, std::vector<double>& sums);

  const scene::Scene* scene_;
  DensityTrainConfig cfg_;
  Schedule planned_;  // the schedule as configured, before any refit
  DensityModel model_;
  nn::Adam adam_;  // groups: grid (lr_grid), network (lr_net); rebuilt at upsampling (TensoRF)
  int iteration_ = 0;
  SyncTotals sync_;
  float l1_weight_ = 0;
  std::unique_ptr<scene::RaySampler> sampler_;
  // 1 for each training pixel (RaySampler's pixel index) on the backdrop; empty: no backdrop term.
  std::vector<uint8_t> backdrop_;
  void build_backdrop();
};

// PSNR (and optionally SSIM) of rendered held-out views; `max_views` > 0 takes that many evenly spaced.
struct ViewScore {
  int view = 0;
  double psnr = 0, ssim = -1;
  double backdrop_acc = -1;  // mean opacity over the view's backdrop pixels (-1: the scene has no backdrop)
};
std::vector<ViewScore> evaluate_views(const DensityModel& m, const scene::Scene& scene, int max_views, bool ssim);
double mean_psnr(const std::vector<ViewScore>& v);  // mean of per-view PSNR (as the NeRF papers report)
double mean_backdrop_acc(const std::vector<ViewScore>& v);  // over the views that have one; -1: none


// The training loop (lib/train/training_loop.hpp) around step(): progress lines (iteration, loss, batch
// PSNR, rays/s, ETA) and the trainer's events, periodic atomic checkpoints, the time budget.
struct RunOptions : LoopOptions<StepStats> {
  // With time_budget_s: refit the schedule (DensityTrainer::refit_schedule) when TrainingBudget::refit
  // says, so events and lr decay land inside the budget. Give the trainer the full-length plan
  // (TensoRF's): each refit fits that plan, never a fitted one.
  bool fit_schedule_to_budget = false;
};
struct RunSummary {
  int iterations = 0;     // steps taken in this run
  double seconds = 0;     // training time (checkpoint writes excluded)
  double last_psnr = 0;   // mean batch PSNR over the last log window
};
RunSummary run_density_training(DensityTrainer& trainer, const RunOptions& opt);

}  // namespace stylerf::train
