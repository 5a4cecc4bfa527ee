#include "lib/train/feature_trainer.hpp"

#include <chrono>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <ostream>
#include <sstream>

#include "host/error.hpp"
#include "lib/io/json_fields.hpp"
#include "lib/eval/metrics.hpp"
#include "lib/train/stage_programs.hpp"
#include "lib/train/trainer_state.hpp"
#include "lib/train/training_loop.hpp"
#include "lib/train/reconstruction_loss.hpp"
#include "lib/features/target_cache.hpp"
#include "lib/features/target_gather.hpp"
#include "lib/nn/layout.hpp"
#include "lib/nn/ops.hpp"
#include "lib/scene/rays.hpp"

namespace stylerf::train {

using host::Error;
using host::Tensor;
using nlohmann::json;

// ---- config ------------------------------------------------------------------------------------------------
#define FEATURE_FIELD_FIELDS rank, channels, init_scale  // FeatureFieldConfig's, flat in the config's JSON
#define FEATURE_TRAIN_FIELDS \
  iters, batch, patch, lr_grid, lr_basis, lr_decoder, beta1, beta2, lr_decay_ratio, tv, content_weight, seed, \
      patches_per_step

json FeatureTrainConfig::to_json() const {
  json j{{"profile", model::decoder_profile_name(profile)}};
  STYLERF_JSON_PUT_FIELDS(j, field, FEATURE_FIELD_FIELDS);
  STYLERF_JSON_PUT_FIELDS(j, *this, FEATURE_TRAIN_FIELDS);
  return j;
}

FeatureTrainConfig FeatureTrainConfig::from_json(const json& j) {
  FeatureTrainConfig c;
  c.profile = model::parse_decoder_profile(j.at("profile").get<std::string>());
  STYLERF_JSON_GET_FIELDS(j, c.field, FEATURE_FIELD_FIELDS);
  json with_defaults = {{"patches_per_step", 1}};  // absent from checkpoints written before it existed
  with_defaults.update(j);
  STYLERF_JSON_GET_FIELDS(with_defaults, c, FEATURE_TRAIN_FIELDS);
  return c;
}

FeatureTrainConfig default_feature_config(const scene::Scene& scene, model::DecoderProfile profile) {
  FeatureTrainConfig c;
  c.profile = profile;
  const bool blender = scene.format == "blender";
  c.field.rank = blender ? std::array<int, 3>{48, 48, 48} : std::array<int, 3>{48, 12, 12};
  c.tv = blender ? 10.0f : 80.0f;
  // The fast decoder starts from AdaIN's trained weights and is fine-tuned; the PlainDecoder starts from
  // random weights and needs a larger step. Fast: 2e-4 measured better than 1e-4 on lego (30 min: 23.12 vs 22.91 dB).
  c.lr_decoder = profile == model::DecoderProfile::Fast ? 2e-4f : 5e-4f;
  // The fast decoder's patch loss is the pixel MSE alone; the paper's adds (relu3_1 + relu4_1 MSE) / 10.
  // Fern at 1008x756, 30 min on one density checkpoint: decoded 22.10 dB against 20.70 dB, 5157 steps
  // against 3557 (no VGG pass in a patch step), and a lower feature MSE too (1.19 vs 1.24; docs/results.md).
  c.content_weight = profile == model::DecoderProfile::Fast ? 0.0f : 0.1f;
  return c;
}

void FeatureTrainConfig::validate() const {
  using host::SettingError;
  if (iters < 1) throw SettingError("iters", "must be >= 1, got " + std::to_string(iters));
  if (batch < 1) throw SettingError("batch", "must be >= 1, got " + std::to_string(batch));
  if (patch < 8 || patch % 8) throw SettingError("patch", "must be a positive multiple of 8, got " + std::to_string(patch));
  for (auto [field, lr] : {std::pair{"lr_grid", lr_grid}, std::pair{"lr_basis", lr_basis}, std::pair{"lr_decoder", lr_decoder}})
    if (!(lr > 0.0f) || !std::isfinite(lr)) throw SettingError(field, "must be a positive number, got " + std::to_string(lr));
  if (patches_per_step < 1 || patches_per_step > 1024)
    throw SettingError("patches_per_step", "must be in [1, 1024], got " + std::to_string(patches_per_step));
  if (!(tv >= 0.0f) || !std::isfinite(tv)) throw SettingError("tv", "must be >= 0, got " + std::to_string(tv));
  if (!(content_weight >= 0.0f) || !std::isfinite(content_weight))
    throw SettingError("content_weight", "must be >= 0, got " + std::to_string(content_weight));
}

// ---- trainer -----------------------------------------------------------------------------------------------
FeatureTrainer::FeatureTrainer(const scene::Scene& scene, const model::Geometry& density, const FeatureTrainConfig& cfg,
                               std::ostream* log)
    : scene_(&scene), cfg_(cfg) {
  cfg_.validate();
  model_ = model::FeatureModel::create(density, cfg_.field, cfg_.profile, cfg_.seed);
  init(log);
  init_background_feature();
}

void FeatureTrainer::init_background_feature() {
  nn::Param& bg = model_.field.background;
  if (!bg.value.defined()) return;
  // relu3_1 of an image of the background colour: reflect padding keeps a constant image constant, so every
  // pixel of the map holds the same 256 values; take the map's mean.
  const auto& c = model_.geo.background;
  const int n = 32;
  std::vector<float> img(size_t(3) * n * n);
  for (int ch = 0; ch < 3; ++ch) std::fill(img.begin() + size_t(ch) * n * n, img.begin() + size_t(ch + 1) * n * n, c[ch]);
  const nn::VggFeatures f = vgg_.forward(Tensor::from_host(img, {1, 3, n, n}, "background image"), 3, false);
  const auto v = f[2].to_host();
  const int C = int(f[2].dim(1)), px = int(f[2].dim(2) * f[2].dim(3));
  if (C != int(bg.value.numel())) throw Error("train-features: relu3_1 has " + std::to_string(C) + " channels");
  std::vector<float> mean(size_t(C), 0.0f);
  for (int ch = 0; ch < C; ++ch) {
    double s = 0;
    for (int i = 0; i < px; ++i) s += v[size_t(ch) * px + i];
    mean[size_t(ch)] = float(s / px);
  }
  bg.value.upload(mean);
}

FeatureTrainer::FeatureTrainer(const scene::Scene& scene, const io::Checkpoint& ck, std::ostream* log)
    : scene_(&scene) {
  read_trainer_state(ck, "trainer", [&](const json& t) {
    cfg_ = FeatureTrainConfig::from_json(t.at("config"));
    iteration_ = t.at("iteration").get<int>();
  });
  model_ = model::FeatureModel::load(ck);
  init(log);
  adam_.load(ck, "", model_.params());
}

void FeatureTrainer::init(std::ostream* log) {
  adam_ = nn::Adam({{"grid", cfg_.lr_grid}, {"basis", cfg_.lr_basis}, {"decoder", cfg_.lr_decoder}}, cfg_.beta1,
                   cfg_.beta2);
  vgg_ = nn::VggEncoder::load_default();
  features::TargetCacheOptions to;
  to.log = log;
  targets_ = features::load_or_compute_targets(*scene_, vgg_, to);
  // Samplers restart from a seed derived from the iteration (their state is not checkpointed).
  const uint64_t s = cfg_.seed * 0x9E3779B97F4A7C15ULL + uint64_t(iteration_);
  rays_ = std::make_unique<features::FeatureRaySampler>(*scene_, s);
  patches_ = std::make_unique<features::PatchSampler>(*scene_, s + 1, cfg_.patch);
}

void FeatureTrainer::set_total_iters(int iters) {
  if (iters < 1) throw Error("train-features: iterations must be >= 1");
  cfg_.iters = iters;
}

void FeatureTrainer::set_patches_per_step(int n) {
  FeatureTrainConfig c = cfg_;
  c.patches_per_step = n;
  c.validate();
  cfg_.patches_per_step = n;
}

static double read_scalar(const Tensor& t) { return t.to_host()[0]; }

double FeatureTrainer::view_feature_mse(int view) {
  if (view < 0 || view >= int(scene_->train.size())) throw Error("view_feature_mse: no training view " + std::to_string(view));
  const scene::Camera& cam = scene_->train[size_t(view)].camera;
  const scene::Rays rays = scene::camera_rays(*scene_, cam);
  const int64_t R = int64_t(rays.size());
  std::vector<float> xy(size_t(R) * 2);
  for (int64_t i = 0; i < R; ++i) {
    xy[size_t(2 * i)] = float(i % cam.width) + 0.5f;
    xy[size_t(2 * i + 1)] = float(i / cam.width) + 0.5f;
  }
  Tensor target = features::gather_targets(targets_.maps, Tensor::from_host(std::vector<int32_t>(size_t(R), view), {R}, "view"),
                                           Tensor::from_host(xy, {R, 2}, "pixel positions"));
  model::RayResult r = model_.field.render(model_.geo, Tensor::from_host(rays.origins, {R, 3}, "view origins"),
                                           Tensor::from_host(rays.directions, {R, 3}, "view directions"), {}, nullptr);
  return read_scalar(nn::mse_forward(r.value, target));
}

FeatureStepStats FeatureTrainer::ray_step(int k) {
  // The batch in patches_per_step slices, dealt round robin over the ranks: every rank draws the whole
  // batch and renders its slices, with the jitter the whole batch draws for those rays; the loss is the
  // whole batch's mean. One slice in one process: the batch at once.
  host::Dist& dist = host::Dist::world();
  const int64_t R = cfg_.batch;
  const int S = cfg_.patches_per_step;
  if (R < S) throw Error("train-features: a batch of " + std::to_string(R) + " rays cannot be cut in " +
                         std::to_string(S) + " slices (--batch, --patches-per-step)");
  const bool batched = S > 1 || dist.size() > 1;
  const features::FeatureRays all = rays_->next(cfg_.batch);
  GradientSum grads;
  std::vector<double> sums(3, 0.0);  // mse, samples, kept
  for (int j = 0; j < S; ++j) {
    if (!my_share(j, dist)) continue;
    const int64_t lo = R * j / S, n = R * (j + 1) / S - lo;
    const features::FeatureRays fr = features::slice(all, size_t(lo), size_t(n));
    Tensor o = Tensor::from_host(fr.rays.origins, {n, 3}, "feature batch origins");
    Tensor d = Tensor::from_host(fr.rays.directions, {n, 3}, "feature batch directions");
    Tensor target = features::gather_targets(targets_.maps, fr.view_tensor(), fr.pixel_xy_tensor());
    model::FeatureField::Context ctx;
    model::RayOptions opt;
    opt.jitter = true;
    opt.seed = static_cast<uint32_t>(cfg_.seed * 7919 + uint64_t(k));
    opt.ray_base = uint32_t(lo);
    model::RayResult r = model_.field.render(model_.geo, o, d, opt, &ctx);
    sums[0] += read_scalar(nn::mse_forward(r.value, target)) * double(n) / double(R);
    sums[1] += double(r.samples);
    sums[2] += double(r.kept);
    model_.field.render_backward(model_.geo, ctx, nn::mse_backward(r.value, target, float(double(n) / double(R))),
                                 Tensor());
    if (batched) grads.add(model_.params());
  }
  if (batched) {
    dist.allreduce_sum(sums);
    sync_.add(grads.average(model_.params(), 1.0, dist));  // the slices' terms add up
  }
  FeatureStepStats st;
  st.feature_mse = sums[0];
  st.samples = int64_t(sums[1]);
  st.kept = int64_t(sums[2]);
  st.rays = R;
  return st;
}

FeatureStepStats FeatureTrainer::patch_step(int k, const features::Patch& p, int j, GradientSum* sum) {
  FeatureStepStats st;
  st.patch = true;
  const int s = model_.stride();
  const int h = p.height / s, w = p.width / s;
  const int64_t R = int64_t(h) * w;
  Tensor o = Tensor::from_host(p.rays.origins, {R, 3}, "patch origins");
  Tensor d = Tensor::from_host(p.rays.directions, {R, 3}, "patch directions");
  model::FeatureField::Context fctx;
  model::RayOptions opt;
  opt.jitter = true;
  opt.seed = static_cast<uint32_t>(cfg_.seed * 7919 + uint64_t(k));
  opt.ray_base = uint32_t(int64_t(j) * R);  // each patch of a step its own jitter
  model::RayResult r = model_.field.render(model_.geo, o, d, opt, &fctx);
  Tensor map = nn::rows_to_image(r.value, h, w);
  nn::ConvStack::Ctx dctx;
  Tensor rgb = model_.decoder.forward(map, &dctx);
  const Tensor gt = p.rgb_tensor();
  host::expect_shape(rgb, gt.shape(), "train-features patch step", "decoded patch");

  // VGG of the true patch first (no activations kept), then of the decoded one (kept for backward); neither
  // when the loss is pixels alone (the fast recipe).
  const nn::VggFeatures ft = cfg_.content_weight > 0 ? vgg_.forward(gt, 4, false) : nn::VggFeatures{};
  const ReconstructionLoss loss = reconstruction_loss(vgg_, rgb, gt, ft, cfg_.content_weight);
  Tensor dmap = model_.decoder.backward(dctx, loss.drgb, true);
  model_.field.render_backward(model_.geo, fctx, nn::rows_to_image_backward(dmap), Tensor());
  if (sum) sum->add(model_.params());
  st.pixel_mse = loss.pixel_mse;
  st.content = cfg_.content_weight * loss.feature_mse;
  st.samples = r.samples;
  st.kept = r.kept;
  st.rays = R;
  return st;
}

FeatureStepStats FeatureTrainer::patch_steps(int k) {
  host::Dist& dist = host::Dist::world();
  const int B = cfg_.patches_per_step;
  if (B == 1 && dist.size() == 1) return patch_step(k, patches_->next(model_.stride()), 0, nullptr);
  // Every rank draws every patch of the step (the same stream) and renders its own share.
  GradientSum sum;
  FeatureStepStats st;
  std::vector<double> sums(5, 0.0);  // pixel mse, content, samples, kept, rays
  for (int j = 0; j < B; ++j) {
    const features::Patch p = patches_->next(model_.stride());
    if (!my_share(j, dist)) continue;
    const FeatureStepStats one = patch_step(k, p, j, &sum);
    sums[0] += one.pixel_mse, sums[1] += one.content;
    sums[2] += double(one.samples), sums[3] += double(one.kept), sums[4] += double(one.rays);
  }
  dist.allreduce_sum(sums);
  sync_.add(sum.average(model_.params(), B, dist));
  st.patch = true;
  st.pixel_mse = sums[0] / B;
  st.content = sums[1] / B;
  st.samples = int64_t(sums[2]);
  st.kept = int64_t(sums[3]);
  st.rays = int64_t(sums[4]);
  return st;
}

FeatureStepStats FeatureTrainer::step() {
  const auto t0 = std::chrono::steady_clock::now();
  const int k = iteration_ + 1;
  model_.zero_grad();
  FeatureStepStats st = (k % 2 == 1) ? ray_step(k) : patch_steps(k);
  const double loss = st.patch ? st.pixel_mse + st.content : st.feature_mse;
  if (!std::isfinite(loss))
    throw Error("train-features: the loss is " + std::to_string(loss) + " at iteration " + std::to_string(k) +
                " (diverged; try lower learning rates or another --seed)");
  // The regulariser after the sums over slices and ranks: every rank adds the same term once.
  const field::VMGrid grid = model_.field.head.grid();
  if (cfg_.tv > 0) field::tv_backward(grid, cfg_.tv * 2e-2f, model_.field.head.grid_param().grad_buffer());
  // lr decays geometrically to lr_decay_ratio over the run (TensoRF's lr_factor per step).
  const float lr_scale = std::pow(cfg_.lr_decay_ratio, float(k - 1) / float(std::max(1, cfg_.iters)));
  adam_.step(model_.params(), lr_scale);
  iteration_ = k;
  if (cfg_.finite_check_every > 0 && k % cfg_.finite_check_every == 0) {
    const std::string bad = model_.first_nonfinite();
    if (!bad.empty())
      throw Error("train-features: parameter '" + bad + "' holds NaN or infinite values after iteration " +
                  std::to_string(k));
  }
  st.iteration = k;
  st.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return st;
}

void FeatureTrainer::save(const std::string& path, const json& scene_meta, const json& density_meta) {
  const std::string bad = model_.first_nonfinite();
  if (!bad.empty())
    throw Error("train-features: parameter '" + bad + "' holds NaN or infinite values at iteration " +
                std::to_string(iteration_) + "; checkpoint " + path + " not written");
  io::Checkpoint ck;
  ck.kind = "features";
  model_.save(ck);
  ck.meta["scene"] = scene_meta;
  ck.meta["density"] = density_meta;
  ck.meta["trainer"] = {{"config", cfg_.to_json()}, {"iteration", iteration_}};
  adam_.save(ck, "");
  io::save_checkpoint(path, ck);
}

// ---- evaluation --------------------------------------------------------------------------------------------
std::vector<DecodedScore> evaluate_decoded(const model::FeatureModel& m, const scene::Scene& scene, int max_views,
                                           bool ssim) {
  const int n = static_cast<int>(scene.test.size());
  std::vector<int> ids;
  const int count = (max_views <= 0 || max_views >= n) ? n : max_views;
  for (int i = 0; i < count; ++i) ids.push_back(static_cast<int>(int64_t(i) * n / count));
  std::vector<DecodedScore> out;
  for (int id : ids) {
    const scene::View& v = scene.test[size_t(id)];
    if (v.rgb.empty()) throw Error("evaluate: test view " + v.image_path + " has no image loaded");
    const auto r = m.render_decoded(scene, v.camera);
    DecodedScore s;
    s.view = id;
    s.psnr = eval::psnr(r.rgb, v.rgb);
    if (ssim)
      s.ssim = eval::ssim(eval::interleaved_to_planar(r.rgb, r.width, r.height), eval::interleaved_to_planar(v.rgb, r.width, r.height), r.width,
                          r.height, 3);
    out.push_back(s);
  }
  return out;
}

// ---- run loop ----------------------------------------------------------------------------------------------
namespace {

// The feature stage in the training loop: the window's feature MSE (ray steps), patch PSNR and content
// loss (patch steps), rays/s.
class FeatureLoopStage : public TrainerLoopStage<FeatureTrainer, FeatureRunOptions, FeatureStepStats> {
 public:
  FeatureLoopStage(FeatureTrainer& t, const FeatureRunOptions& o) : TrainerLoopStage(t, o) {}
  int total() const override { return t_.config().iters; }
  void step(bool) override {
    last_ = t_.step();
    rays_ += double(last_.rays);
    ++n_;
    if (last_.patch)
      pixel_mse_ += last_.pixel_mse, content_ += last_.content, ++patches_;
    else
      feature_mse_ += last_.feature_mse, ++ray_steps_;
  }
  std::string window_line(double per_it) override {
    std::ostringstream l;
    l << std::fixed << std::setprecision(4);
    if (ray_steps_) l << "  feature mse " << feature_mse_ / ray_steps_;
    if (patches_) {
      l << "  patch mse " << pixel_mse_ / patches_ << " (psnr " << std::setprecision(2)
        << eval::psnr_from_mse(pixel_mse_ / patches_) << ")";
      if (t_.config().content_weight > 0) l << " content " << std::setprecision(4) << content_ / patches_;
    }
    l << std::setprecision(0) << "  " << rays_ / n_ / per_it << " rays/s";
    keep_window_figures();
    rays_ = feature_mse_ = pixel_mse_ = content_ = 0;
    n_ = ray_steps_ = patches_ = 0;
    return l.str();
  }
  // The run's length is its lr decay horizon: refitted to the budget as the step rate becomes known.
  void refit(const Refit& r) override { t_.set_total_iters(r.total_iters); }
  void save() override {
    if (!o_.checkpoint.empty()) t_.save(o_.checkpoint, o_.scene_meta, o_.density_meta);
  }
  void end_of_run() override { keep_window_figures(); }
  double last_patch_psnr = 0, last_feature_mse = 0;

 private:
  void keep_window_figures() {
    if (patches_) last_patch_psnr = eval::psnr_from_mse(pixel_mse_ / patches_);
    if (ray_steps_) last_feature_mse = feature_mse_ / ray_steps_;
  }

  double rays_ = 0, feature_mse_ = 0, pixel_mse_ = 0, content_ = 0;
  int n_ = 0, ray_steps_ = 0, patches_ = 0;
};

}  // namespace

FeatureRunSummary run_feature_training(FeatureTrainer& trainer, const FeatureRunOptions& opt) {
  FeatureLoopStage stage(trainer, opt);
  const LoopResult r = run_training_loop(stage, loop_control(opt, feature_stage_programs(trainer.model())));
  return {r.iterations, r.seconds, stage.last_patch_psnr, stage.last_feature_mse};
}

nlohmann::json density_source_meta(const std::string& density_path, const io::Checkpoint& density) {
  return {{"path", std::filesystem::absolute(density_path).string()},
          {"iteration", density.meta.value("trainer", nlohmann::json::object()).value("iteration", 0)}};
}

}  // namespace stylerf::train
