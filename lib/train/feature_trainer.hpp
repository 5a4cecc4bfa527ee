// The feature stage (StyleRF stage 2): a VM grid of VGG-19 relu3_1 features and a decoder, trained over
// the frozen geometry of a density checkpoint (lib/model/feature_model.hpp).
//
// Steps alternate, as the authors train:
//   ray steps (odd iterations): `batch` random rays over every training pixel -> rendered features ->
//     MSE against the relu3_1 targets bilinearly upsampled at each ray's pixel (lib/features);
//   patch steps (even iterations): a random patch (256 px, or the whole image where smaller) -> features
//     rendered at the profile's stride -> decoder -> RGB; loss = pixel MSE + (MSE of relu4_1 + MSE of
//     relu3_1 between VGG of the decoded and of the true patch) / 10;
//   both: + feature TV on the grid's planes (weight tv, times TensoRF's 2e-2 plane-TV scale).
// Adam (betas 0.9, 0.99) with groups grid (lr_grid), basis (lr_basis), decoder (lr_decoder), all decayed
// to lr_decay_ratio of their value over the run, as TensoRF's grids are.
// Empty space renders as 0 (no background feature): the decoder learns the background colour from the
// zero features there; the per-ray loss on background pixels is a constant it cannot lower.
#pragma once
#include <functional>
#include <iosfwd>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "lib/features/feature_sampler.hpp"
#include "lib/features/feature_targets.hpp"
#include "lib/model/feature_model.hpp"
#include "lib/nn/adam.hpp"
#include "lib/nn/vgg.hpp"
#include "lib/scene/scene.hpp"
#include "lib/train/budget.hpp"
#include "lib/train/data_parallel.hpp"
#include "lib/train/training_loop.hpp"

namespace stylerf::train {

struct FeatureTrainConfig {
  model::DecoderProfile profile = model::DecoderProfile::Fast;
  model::FeatureFieldConfig field;
  int iters = 10000;
  int batch = 4096;    // rays per ray step
  int patch = 256;     // patch side (pixels) of a patch step
  // lr_basis: TensoRF uses 1e-3; 1e-2 learns the 256-channel basis faster in the short runs a CPU affords
  // (measured on the generated scene, 300 iterations: decoded PSNR 16.9 dB at 1e-3, 17.7 at 1e-2, 17.9 at 3e-2).
  float lr_grid = 0.02f, lr_basis = 1e-2f, lr_decoder = 1e-4f;  // paper profile (from scratch): 5e-4
  float beta1 = 0.9f, beta2 = 0.99f;
  float lr_decay_ratio = 0.1f;
  float tv = 10.0f;               // StyleRF: Blender 10, LLFF 80
  float content_weight = 0.1f;    // (relu4_1 MSE + relu3_1 MSE) x this in patch steps (the paper's 0.1; fast: 0)
  // Patches a patch step averages the gradients of, and slices a ray step's batch is rendered in (their
  // gradients summed); over MPI ranks both are dealt round robin (lib/train/data_parallel.hpp): 1 rank
  // taking N of them takes the step N ranks take.
  int patches_per_step = 1;
  uint64_t seed = 0;
  int finite_check_every = 50;

  // Every field's rule, in one place: a host::SettingError naming the field.
  void validate() const;
  nlohmann::json to_json() const;
  static FeatureTrainConfig from_json(const nlohmann::json& j);
};

// StyleRF's settings for the scene's format (ranks, TV) and the profile (decoder lr, patch loss).
FeatureTrainConfig default_feature_config(const scene::Scene& scene, model::DecoderProfile profile);

struct FeatureStepStats {
  int iteration = 0;
  bool patch = false;       // a patch step (else a ray step)
  double feature_mse = -1;  // ray steps
  double pixel_mse = -1, content = -1;  // patch steps: pixel MSE and the weighted VGG term
  double seconds = 0;
  int64_t samples = 0, kept = 0, rays = 0;
};

class FeatureTrainer {
 public:
  // A fresh model over the geometry of `density` (a density checkpoint's), targets from `targets`.
  FeatureTrainer(const scene::Scene& scene, const model::Geometry& density, const FeatureTrainConfig& cfg,
                 std::ostream* log);
  // Resumes from a feature checkpoint written by save().
  FeatureTrainer(const scene::Scene& scene, const io::Checkpoint& ck, std::ostream* log);

  FeatureStepStats step();
  int iteration() const { return iteration_; }
  bool done() const { return iteration_ >= cfg_.iters; }
  const FeatureTrainConfig& config() const { return cfg_; }
  model::FeatureModel& model() { return model_; }
  void set_total_iters(int iters);
  void set_patches_per_step(int n);
  // The gradient sums over MPI ranks or a step's patches so far (lib/train/data_parallel.hpp).
  const SyncTotals& sync() const { return sync_; }
  // MSE of the rendered features (no jitter) against the targets over every pixel of training view
  // `view`: a fixed yardstick, unlike the loss of random batches.
  double view_feature_mse(int view);
  // meta: scene (scene::scene_meta) and the density checkpoint it came from.
  void save(const std::string& path, const nlohmann::json& scene_meta, const nlohmann::json& density_meta);

 private:
  void init(std::ostream* log);
  // A fresh model's background feature starts as VGG's relu3_1 of the background colour.
  void init_background_feature();
  FeatureStepStats ray_step(int k);
  // A patch step: cfg_.patches_per_step patches (this rank's share of them), their gradients averaged.
  FeatureStepStats patch_steps(int k);
  // One patch, the step's j-th; its gradients go to `sum` when given.
  FeatureStepStats patch_step(int k, const features::Patch& p, int j, GradientSum* sum);

  const scene::Scene* scene_;
  FeatureTrainConfig cfg_;
  model::FeatureModel model_;
  nn::Adam adam_;
  nn::VggEncoder vgg_;
  features::FeatureTargets targets_;
  std::unique_ptr<features::FeatureRaySampler> rays_;
  std::unique_ptr<features::PatchSampler> patches_;
  int iteration_ = 0;
  SyncTotals sync_;
};

// Decoded-RGB PSNR (and SSIM) of held-out views; max_views > 0 takes that many evenly spaced.
struct DecodedScore {
  int view = 0;
  double psnr = 0, ssim = -1;
};
std::vector<DecodedScore> evaluate_decoded(const model::FeatureModel& m, const scene::Scene& scene, int max_views,
                                           bool ssim);

// The training loop (lib/train/training_loop.hpp) around step(): progress lines (losses, PSNR of the
// patches, rays/s, ETA), periodic atomic checkpoints, a time budget that refits the run's length (and so
// its lr decay) from the measured rate.
struct FeatureRunOptions : LoopOptions<FeatureStepStats> {
  FeatureRunOptions() {
    log_every = 50;
    checkpoint_every = 500;
  }
  nlohmann::json density_meta;  // density_source_meta, recorded in the checkpoint
};
struct FeatureRunSummary {
  int iterations = 0;
  double seconds = 0;
  double last_patch_psnr = 0, last_feature_mse = 0;
};
FeatureRunSummary run_feature_training(FeatureTrainer& trainer, const FeatureRunOptions& opt);

// What a feature checkpoint records of the density checkpoint it was trained over (FeatureRunOptions::
// density_meta): its absolute path and the iteration it had reached.
nlohmann::json density_source_meta(const std::string& density_path, const io::Checkpoint& density);

}  // namespace stylerf::train
