// The style stage (StyleRF stage 3): trains the stylizer (SICT + DST) and fine-tunes the decoder over a
// frozen feature model, one style image per step (lib/model/style_model.hpp).
//
// A rendered step: a style image resized to style_size^2 (the paper's 512; style_size == style_crop: the
// whole image, at the scale inference uses), a random style_crop^2 crop -> VGG taps (style
// targets) and its relu3_1 rows -> DST's style code; a random training patch (256 px, or the whole image
// where smaller) rendered with SICT in training mode (batch statistics of its kept samples) -> DST ->
// decoder -> RGB; losses (lib/train/style_losses.hpp), masked by opacity on scenes with a background;
// backward through VGG, the decoder, DST, the style branch and SICT; Adam (betas 0.9, 0.99) at lr_stylizer
// for the stylizer and lr_decoder for the decoder; SICT's running statistics then move (momentum 1e-4).
//
// Departures from the authors' loop, both for runs of minutes rather than 25k GPU steps:
//  - SICT's running statistics start from the statistics of the kept samples of a few training patches
//    (measured before the first step) instead of (0, 1): at momentum 1e-4 they would need ~10k steps to
//    leave their initial values, and inference uses nothing else;
//  - decoder_warm > 0: before everything else, the decoder alone learns to invert VGG: the relu3_1 of the
//    step's style crop in, the crop out (pixel MSE + (relu3_1 + relu4_1 MSE) / 10, stage 2's patch loss).
//    Stage 2 taught it one scene's photographs; the style loss asks for painted textures, which a decoder
//    that never drew one renders blurred, and the style loss is mostly about fine texture (docs/experiments.md);
//  - warm_start > 0: the next steps are 2D steps on a map per training view (no rendering), then rendered
//    steps fine-tune. warm_maps picks the maps (lib/train/warm_maps.hpp): stage 2's cached relu3_1 targets
//    (each target pixel a "point" of weight 1) or the feature field rendered once per view. Fast profile
//    only (the maps are at relu3_1's resolution, the fast profile's map resolution). Under --minutes it
//    ends early once warm_share of the minutes is spent, and warm_start then records the steps it took;
//  - style_decoder VggAdain (off by default): the maps are drawn by VGG's frozen relu3_1 -> relu4_1 and
//    AdaIN's pretrained decoder (fine-tuned at lr_decoder) instead of stage 2's decoder, which has drawn
//    one scene's photographs and must learn painted texture within the run (model::StyleDecoderKind);
//    VggAdainRelu4 also re-normalises the tail's relu4_1 output to the style's relu4_1 statistics.
#pragma once
#include <functional>
#include <iosfwd>
#include <memory>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <unordered_map>
#include <vector>

#include "lib/features/feature_sampler.hpp"
#include "lib/features/feature_targets.hpp"
#include "lib/model/style_model.hpp"
#include "lib/style/style_image.hpp"
#include "lib/nn/adam.hpp"
#include "lib/nn/vgg.hpp"
#include "lib/scene/scene.hpp"
#include "lib/train/budget.hpp"
#include "lib/train/data_parallel.hpp"
#include "lib/train/training_loop.hpp"
#include "lib/train/style_losses.hpp"
#include "lib/train/warm_maps.hpp"

namespace stylerf::train {

struct StyleTrainConfig {
  style::SictMode sict = style::SictMode::VolumeAdaptive;
  bool dst_bias = true;
  // The content skip beside DST (lib/style/content_skip.hpp); off: the paper's module.
  bool content_skip = false;
  int iters = 25000;
  int patch = 256;
  int style_size = 512, style_crop = 256;
  float lr_stylizer = 1e-4f, lr_decoder = 1e-5f;
  float beta1 = 0.9f, beta2 = 0.99f;
  float lr_decay_ratio = 1.0f;  // lr at the end of the run over lr at its start (the stylizer's: at its first step)
  StyleLossWeights weights;
  int decoder_warm = 0;         // steps before all others that train the decoder alone to invert VGG of style crops
  int warm_start = 0;           // 2D steps next (fast profile)
  // Under a time budget the warm start also ends once this fraction of the run's minutes is spent (1: only
  // its step count ends it). Its steps cost a third of a rendered step, but the rendered steps that follow
  // are what the test views are scored on; a fixed count would fill a short run with 2D steps alone.
  float warm_share = 1.0f;
  WarmMaps warm_maps = WarmMaps::Vgg;  // what those steps read
  model::StyleDecoderKind style_decoder = model::StyleDecoderKind::Stage2;  // which decoder draws the maps
  // Styles (each with its own patch) a step averages the gradients of; over MPI ranks they are dealt round
  // robin (lib/train/data_parallel.hpp), and 1 rank taking N of them takes the step N ranks take.
  int styles_per_step = 1;
  int running_init_patches = 4; // patches measured for SICT's initial running statistics (0: PyTorch's 0/1)
  // Saved with the model: the rays per block inference uses by default (kSupersampleByScene: settled here by
  // the scene, model::default_inference_supersample).
  int inference_supersample = 1;
  bool decoder_phases = false;    // VggAdain: the tail's pool at all four grid offsets (StyleModel::decoder_phases)
  uint64_t seed = 0;
  int finite_check_every = 50;

  // Every field's rule, in one place: a host::SettingError naming the field.
  void validate() const;
  nlohmann::json to_json() const;
  static StyleTrainConfig from_json(const nlohmann::json& j);
};

// Style images of a folder (.jpg/.jpeg/.png, sorted by name; files that cannot be decoded are skipped and
// named on `log`), `holdout` of them (evenly spread over the sorted list) never trained on.
struct StyleSet {
  std::vector<std::string> train, holdout;
  static StyleSet from_dir(const std::string& dir, int holdout, std::ostream* log = nullptr);
  nlohmann::json to_json() const;
  static StyleSet from_json(const nlohmann::json& j);
};

using style::load_style_image;  // lib/style/style_image.hpp

struct StyleStepStats {
  int iteration = 0;
  bool warm = false;      // a 2D warm-start step
  bool decoder_warm = false;  // a decoder warm-up step (content = its inversion loss, style 0)
  bool skipped = false;   // the patch had no opaque position (nothing to learn from)
  double content = 0, style = 0, seconds = 0;
  int64_t rays = 0, kept = 0;
  std::string style_name;
};

struct HoldoutLoss {
  double content = 0, style = 0;
  int styles = 0;
};

class StyleTrainer {
 public:
  StyleTrainer(const scene::Scene& scene, model::FeatureModel features, StyleSet styles, const StyleTrainConfig& cfg,
               std::ostream* log);
  // Resumes from a style checkpoint written by save(). One of a run that averaged its weights (the
  // retired ema_decay, docs/experiments.md) holds the average as its model, and one of a run with a frozen
  // decoder (lr_decoder 0) cannot go on as it ran: both are refused, naming the file and the field.
  StyleTrainer(const scene::Scene& scene, const io::Checkpoint& ck, std::ostream* log);

  StyleStepStats step();
  // The generator of sub-batch g's draws (g = step index x styles_per_step + its place in the step): its
  // style (uniform over the training styles), the style crop's corner (when smaller than the image), then
  // its patch (PatchSampler::next), in that order.
  static std::mt19937_64 sub_batch_draws(uint64_t seed, int64_t g) {
    return std::mt19937_64(seed * 0x9E3779B97F4A7C15ULL + uint64_t(g) * 0xD1B54A32D192ED03ULL + 1);
  }
  int iteration() const { return iteration_; }
  bool done() const { return iteration_ >= cfg_.iters; }
  void set_total_iters(int iters) { cfg_.iters = iters; }
  void set_styles_per_step(int n) {
    StyleTrainConfig c = cfg_;
    c.styles_per_step = n;
    c.validate();
    cfg_.styles_per_step = n;
  }
  // Where the run stands in [0, 1] for the lr decay; a time-budgeted run passes its elapsed fraction (its
  // step count is only an estimate, refitted as it goes). Unset (< 0): iteration / iters.
  void set_schedule_progress(double f) { schedule_progress_ = f; }
  const StyleTrainConfig& config() const { return cfg_; }
  const StyleSet& styles() const { return styles_; }
  model::StyleModel& model() { return model_; }
  const nn::Adam& optimizer() const { return adam_; }
  // The gradient averagings over ranks (or over a step's styles) so far (lib/train/data_parallel.hpp).
  const SyncTotals& sync() const { return sync_; }
  // Mean losses of a fixed patch (the first training view's centre) under each held-out style (at most
  // max_styles of them), SICT in inference mode.
  HoldoutLoss evaluate_holdout(int max_styles = 0);
  // Style images encoded once and kept (see encoded_style), and whole views' content targets (see
  // content_target); forgetting them frees their memory and changes no result (tests compare the two).
  size_t encoded_styles() const { return encoded_styles_.size(); }
  size_t content_targets() const { return content_targets_.size(); }
  void forget_encoded_styles() {
    encoded_styles_.clear();
    encoded_style_bytes_ = 0;
    content_targets_.clear();
    content_target_bytes_ = 0;
  }
  void save(const std::string& path, const nlohmann::json& scene_meta);

 private:
  void init(std::ostream* log);
  void init_running_stats(std::ostream* log);
  // What a step needs of a style image: relu3_1 and relu4_1 (DST's style code, the relu4 decoder's target;
  // the other taps are dropped) and the style loss's targets.
  struct EncodedStyle {
    nn::VggFeatures taps;
    StyleTargets targets;
  };
  // The style image's encoding. With style_size == style_crop every step sees the whole image, and each
  // style is encoded once (the VGG pass of a 256 px image was a third of a 2D step at 128 px); held-out
  // styles are always whole images. Kept up to kEncodedStyleBytes (6 MB a 256 px style), then encoded per use.
  std::shared_ptr<const EncodedStyle> encoded_style(const std::string& path, bool whole_image,
                                                    const std::function<Tensor()>& load);
  static constexpr size_t kEncodedStyleBytes = size_t(1) << 30;
  // relu4_1 of a patch's true colours (the content loss's target). Where the patch is the whole view (lego at
  // 1/4, the demo's scene) each view's is kept (up to kContentTargetBytes), else computed per step.
  Tensor content_target(const features::Patch& p);
  static constexpr size_t kContentTargetBytes = size_t(256) << 20;
  // One style of a step (sub-batch g of the run: its draws come from g alone; rendered_step's `sub` is g).
  enum class StepKind { DecoderWarm, Warm, Rendered };
  StyleStepStats sub_step(int64_t g, StepKind kind);
  StyleStepStats rendered_step(int64_t sub, std::mt19937_64& draw, const StyleTargets& style_targets,
                               const style::StyleCode& code, style::Dst::StyleContext& sctx);
  StyleStepStats warm_step(std::mt19937_64& draw, const StyleTargets& style_targets, const style::StyleCode& code,
                           style::Dst::StyleContext& sctx);
  StyleStepStats decoder_warm_step(const Tensor& style_image, const nn::VggFeatures& style_taps);
  void set_group_lr(const std::string& group, float lr);  // "stylizer" or "decoder": its Adam rate this step
  void set_step_lrs(int k, bool decoder_warm);            // both groups' rates for step k (lr decay, warm-up)

  const scene::Scene* scene_;
  StyleTrainConfig cfg_;
  StyleSet styles_;
  model::StyleModel model_;
  nn::Adam adam_;
  nn::VggEncoder vgg_;
  features::FeatureTargets targets_;  // warm start on VGG maps only
  RenderedWarmMaps rendered_maps_;    // warm start on rendered maps only
  double schedule_progress_ = -1;
  double stylizer_start_ = -1;  // the run's progress at the stylizer's first step (its lr decay starts there)
  std::unique_ptr<features::PatchSampler> patches_;
  // Each training style decoded and resized to style_size once (116 styles at 512: 365 MB of host memory).
  std::unordered_map<std::string, io::Image> style_sources_;
  std::unordered_map<std::string, std::shared_ptr<const EncodedStyle>> encoded_styles_;  // by path
  size_t encoded_style_bytes_ = 0;
  std::unordered_map<int64_t, Tensor> content_targets_;  // by the patch's view and corner
  size_t content_target_bytes_ = 0;
  int iteration_ = 0;
  SyncTotals sync_;
  nlohmann::json features_meta_;
};

// The training loop (lib/train/training_loop.hpp) around step(), with held-out losses every eval_every steps.
struct StyleRunOptions : LoopOptions<StyleStepStats> {
  StyleRunOptions() {
    log_every = 10;
    checkpoint_every = 200;
  }
  int eval_every = 100;  // held-out losses every this many steps (0: never)
  int eval_styles = 0;   // held-out styles in that evaluation (0: all)
};
struct StyleRunSummary {
  int iterations = 0;
  double seconds = 0;
  HoldoutLoss last_holdout;
};
StyleRunSummary run_style_training(StyleTrainer& trainer, const StyleRunOptions& opt);

}  // namespace stylerf::train
