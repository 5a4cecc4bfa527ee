#include "lib/train/density_trainer.hpp"

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <iomanip>
#include <ostream>
#include <cmath>
#include <sstream>

#include "host/error.hpp"
#include "lib/io/json_fields.hpp"
#include "lib/eval/metrics.hpp"
#include "lib/scene/masked_background.hpp"
#include "lib/train/stage_programs.hpp"
#include "lib/train/trainer_state.hpp"
#include "lib/train/data_parallel.hpp"
#include "lib/train/training_loop.hpp"
#include "lib/nn/checks.hpp"
#include "lib/nn/ops.hpp"
#include "lib/render/distortion.hpp"

namespace stylerf::train {

using host::Error;
using nlohmann::json;

// ---- config ------------------------------------------------------------------------------------------------
#define DENSITY_SCHEDULE_FIELDS \
  iters, upsample_at, voxels_init, voxels_final, mask_at, lr_decay_ratio, lr_reset_on_upsample
#define DENSITY_TRAIN_FIELDS                                                                              \
  batch, lr_grid, lr_net, beta1, beta2, l1_initial, l1_rest, tv_density, tv_app, alpha_mask, \
      reset_optimizer_on_upsample, seed, batch_slices

json DensityTrainConfig::to_json() const {
  json j{{"model", model.to_json()}, {"schedule", json::object()}};
  STYLERF_JSON_PUT_FIELDS(j["schedule"], schedule, DENSITY_SCHEDULE_FIELDS);
  STYLERF_JSON_PUT_FIELDS(j, *this, DENSITY_TRAIN_FIELDS);
  j["backdrop_weight"] = backdrop_weight;
  j["distortion_weight"] = distortion_weight;
  return j;
}

DensityTrainConfig DensityTrainConfig::from_json(const json& j) {
  DensityTrainConfig c;
  c.model = DensityModelConfig::from_json(j.at("model"));
  STYLERF_JSON_GET_FIELDS(j.at("schedule"), c.schedule, DENSITY_SCHEDULE_FIELDS);
  json with_defaults = {{"batch_slices", 1}};  // absent from checkpoints written before it existed
  with_defaults.update(j);
  STYLERF_JSON_GET_FIELDS(with_defaults, c, DENSITY_TRAIN_FIELDS);
  c.backdrop_weight = j.value("backdrop_weight", 0.0f);  // checkpoints from before the term trained without it
  c.distortion_weight = j.value("distortion_weight", 0.0f);  // likewise
  return c;
}

void DensityTrainConfig::validate() const {
  using host::SettingError;
  auto in_range = [](const char* field, double v, double lo, double hi) {
    if (!std::isfinite(v) || v < lo || v > hi) {
      std::ostringstream m;
      m << "must be a number in [" << lo << ", " << hi << "] (got " << v << ")";
      throw SettingError(field, m.str());
    }
  };
  schedule.validate();
  if (batch < 1 || batch > (1 << 22)) throw SettingError("batch", "must be in [1, 4194304], got " + std::to_string(batch));
  if (batch_slices < 1 || batch_slices > batch)
    throw SettingError("batch_slices", "must be in [1, batch = " + std::to_string(batch) + "], got " +
                                           std::to_string(batch_slices));
  in_range("lr_grid", lr_grid, 1e-8, 10);
  in_range("lr_net", lr_net, 1e-8, 10);
  in_range("beta1", beta1, 0, 0.999999);
  in_range("beta2", beta2, 0, 0.999999);
  for (auto [field, w] : {std::pair{"l1_initial", l1_initial}, std::pair{"l1_rest", l1_rest},
                          std::pair{"tv_density", tv_density}, std::pair{"tv_app", tv_app},
                          std::pair{"backdrop_weight", backdrop_weight},
                          std::pair{"distortion_weight", distortion_weight}})
    in_range(field, w, 0, 1e6);
}

DensityTrainConfig default_density_config(const scene::Scene& scene, bool tensorf_grid) {
  DensityTrainConfig c;
  if (scene.format == "blender") {
    c.model.density_rank = {16, 16, 16};
    c.model.app_rank = {48, 48, 48};
    c.model.act = field::DensityActivation::Softplus;
    c.schedule.iters = 30000;
    c.schedule.voxels_final = 300LL * 300 * 300;
    c.schedule.mask_at = {2000, 4000};
    c.l1_initial = 8e-5f;
    c.l1_rest = 4e-5f;
  } else {
    c.model.density_rank = {16, 4, 4};
    c.model.app_rank = {48, 12, 12};
    c.model.act = field::DensityActivation::Relu;
    c.schedule.iters = 25000;
    // flower.txt's 640^3 is sized for 25k steps; a budget of minutes on a CPU gets ~10x fewer. Measured on
    // fern 1008x756 (10-minute density, then 10-minute features, alone; docs/results.md): 400^3 took 1556
    // steps to 640^3's 1190, held-out 22.25 vs 22.01 dB, decoded 18.64 vs 17.36 dB, a stylised frame 15.9
    // vs 23.8 s (~0.6x the samples a ray: an NDC ray takes |res| / step of them), peak RSS 5.0 vs 6.3 GB.
    // Object captures (no NDC rays, a box about the object) take Blender's 300^3. Measured on bird_figurine
    // 544x960 (9.5-minute density, alone): 300^3 / 400^3 / 640^3 held out 26.22 / 26.25 / 26.17 dB with
    // 291 / 378 / 614 samples a ray, peak RSS 5.0 / 5.7 / 7.1 GB, evaluation 41 / 55 / 102 s for 5 views;
    // the later stages' per-sample buffers and frames scale with the samples. The paper recipe keeps 640^3.
    const int64_t side = tensorf_grid ? 640 : scene.effects.ndc ? kFastLlffFinalSide : kFastObjectFinalSide;
    c.schedule.voxels_final = side * side * side;
    c.schedule.mask_at = {2500};
    c.l1_initial = c.l1_rest = 0.0f;
    c.tv_density = 1.0f;
    c.tv_app = 1.0f;
  }
  // Object captures with real surroundings (the background shell): the box holds a table and the room's near
  // parts, textureless, which the colour loss leaves as a fog spread along the rays. The distortion term
  // gathers each ray's weight into one surface. bird_figurine 544x960, 5-minute density, alone
  // (docs/experiments.md, "The distortion term"): held-out 26.30 -> 26.15 dB (SSIM 0.853 both), 252 -> 151
  // samples a ray, 3171 -> 4574 steps, a view rendered in 8.1 -> 4.4 s, and a depth that shows the bird
  // instead of vertical streaks of fog. Forward-facing and Blender scenes are not measured with it, and the
  // paper recipe keeps TensoRF's losses: off.
  if (scene.effects.background_shell && !tensorf_grid) c.distortion_weight = kShellDistortionWeight;
  c.model.view_dependent = scene.effects.view_dependence;
  // Deferred shading (one MLP evaluation per ray) by default: at equal time it trained lego 1/4 to 33.36 dB
  // in 10 min (9196 steps) against 31.46 dB per sample (2848 steps), and fern 1/8 to 25.68 dB in 30 min,
  // where the per-sample MLP was most of a step. --shading per-sample is TensoRF's.
  c.model.deferred_shading = true;
  c.schedule.upsample_at = {2000, 3000, 4000, 5500};
  c.schedule.voxels_init = 128LL * 128 * 128;
  // Small images: TensoRF's grids are sized for 800 px views; below kSmallImageSide pixels they hold more
  // voxels than there are pixels to supervise them, and a short run never reaches the alpha mask that
  // makes their ~440 samples a ray cheap. There the grid sides are a quarter and three quarters of the
  // image side (min 32). Measured on the generated 128 px scene: 128^3 -> 300^3 reached 14.3 dB in 45 s
  // (58 steps), 32^3 -> 96^3 30.8 dB in 24 s (300 steps). Real scenes at the resolutions measured (lego
  // 1/4: 200 px, fern 1/8: 504 px) keep the format's grids.
  constexpr int kSmallImageSide = 160;
  const int side = std::max(scene.width(), scene.height());
  if (side > 0 && side <= kSmallImageSide) {
    const int64_t init = std::max(32, side / 4), fin = std::max<int64_t>(init, 3 * side / 4);
    c.schedule.voxels_init = init * init * init;
    c.schedule.voxels_final = fin * fin * fin;
  }
  return c;
}

// ---- trainer -----------------------------------------------------------------------------------------------
static std::array<int, 3> res_for(const model::Geometry& g, int64_t voxels) {
  return field::grid_res_for_voxels(g.box_size(), voxels);
}

// The ray sampler's stream for a run resumed at `iteration` (std::mt19937_64 state is not checkpointed:
// a resumed run draws a fresh, still deterministic, stream).
static uint64_t sampler_seed(uint64_t seed, int iteration) { return seed * 0x9E3779B97F4A7C15ULL + uint64_t(iteration); }

DensityTrainer::DensityTrainer(const scene::Scene& scene, const DensityTrainConfig& cfg) : scene_(&scene), cfg_(cfg) {
  cfg_.validate();
  planned_ = cfg_.schedule;
  model::Geometry probe;
  for (int a = 0; a < 3; ++a) probe.box_lo[a] = scene.aabb[0][a], probe.box_hi[a] = scene.aabb[1][a];
  model_ = DensityModel::create(scene, cfg_.model, res_for(probe, cfg_.schedule.voxels_init), cfg_.seed);
  l1_weight_ = cfg_.l1_initial;
  init_optimizer();
  sampler_ = std::make_unique<scene::RaySampler>(scene, sampler_seed(cfg_.seed, 0));
  build_backdrop();
}

double DensityTrainer::backdrop_share() const {
  if (backdrop_.empty()) return 0.0;
  size_t n = 0;
  for (uint8_t b : backdrop_) n += b;
  return double(n) / double(backdrop_.size());
}

void DensityTrainer::build_backdrop() {
  backdrop_.clear();
  if (cfg_.backdrop_weight <= 0 || !scene_->effects.background) return;
  for (const auto& v : scene_->train) {
    const auto m = scene::backdrop_pixels(*scene_, v);
    if (m.empty()) {  // a view without an image: no term at all rather than a mask out of step with the sampler
      backdrop_.clear();
      return;
    }
    backdrop_.insert(backdrop_.end(), m.begin(), m.end());
  }
}

DensityTrainer::DensityTrainer(const scene::Scene& scene, const io::Checkpoint& ck) : scene_(&scene) {
  read_trainer_state(ck, "trainer", [&](const json& t) {
    cfg_ = DensityTrainConfig::from_json(t.at("config"));
    iteration_ = t.at("iteration").get<int>();
    l1_weight_ = t.at("l1_weight").get<float>();
  });
  planned_ = cfg_.schedule;
  model_ = model::load_model(ck);
  init_optimizer();
  adam_.load(ck, "", model_.params());
  sampler_ = std::make_unique<scene::RaySampler>(scene, sampler_seed(cfg_.seed, iteration_));
  build_backdrop();
}

void DensityTrainer::refit_schedule(int total_iters) {
  const Schedule fit = planned_.fitted(std::max(total_iters, iteration_ + 1));
  Schedule next = fit;
  auto merge = [&](const std::vector<int>& done_list, const std::vector<int>& fit_list) {
    std::vector<int> out;
    for (size_t i = 0; i < fit_list.size(); ++i) {
      const int prev = out.empty() ? 0 : out.back();
      if (i < done_list.size() && done_list[i] <= iteration_)
        out.push_back(done_list[i]);  // already fired: history stays as it was
      else
        out.push_back(std::max({fit_list[i], iteration_ + 1, prev + 1}));
    }
    return out;
  };
  next.upsample_at = merge(cfg_.schedule.upsample_at, fit.upsample_at);
  next.mask_at = merge(cfg_.schedule.mask_at, fit.mask_at);
  // No event in the last 10% of the run: an upsample there resets Adam on a larger grid for a handful of
  // steps, a mask update rebuilds it for none. Such events are dropped (a suffix: the lists are sorted and
  // fired events come first); the grid then ends at the size its last kept upsample reaches, which keeps
  // the voxel steps of the events before it unchanged (they are log-linear in the event index).
  const int limit = int(0.9 * double(next.iters));
  auto drop_late = [&](std::vector<int>& v) {
    while (!v.empty() && v.back() > limit && v.back() > iteration_) v.pop_back();
  };
  const auto voxels = next.voxel_list();
  const size_t planned = next.upsample_at.size();
  drop_late(next.upsample_at);
  if (next.upsample_at.size() < planned)
    next.voxels_final = next.upsample_at.empty() ? next.voxels_init : voxels[next.upsample_at.size() - 1];
  drop_late(next.mask_at);
  next.validate();
  cfg_.schedule = next;
}

void DensityTrainer::init_optimizer() {
  adam_ = nn::Adam({{"grid", cfg_.lr_grid}, {"network", cfg_.lr_net}}, cfg_.beta1, cfg_.beta2);
}

void DensityTrainer::slice_terms(const scene::Rays& batch, int64_t lo, int64_t n, int k, std::vector<double>& sums) {
  const int64_t R = int64_t(batch.size());
  const scene::Rays rays = scene::slice(batch, size_t(lo), size_t(n));
  Tensor o = Tensor::from_host(rays.origins, {n, 3}, "batch origins");
  Tensor d = Tensor::from_host(rays.directions, {n, 3}, "batch directions");
  Tensor target = Tensor::from_host(rays.rgb, {n, 3}, "batch colours");
  model::RayContext cache;
  const model::RayResult out =
      model_.render(o, d, true, static_cast<uint32_t>(cfg_.seed * 7919 + uint64_t(k)), &cache, uint32_t(lo));
  // The backdrop term: weight * mean over the batch of acc on backdrop rays (its gradient is constant).
  Tensor dacc;
  if (!backdrop_.empty()) {
    std::vector<float> g(size_t(n), 0.0f);
    const auto acc = out.acc.to_host();
    for (int64_t r = 0; r < n; ++r)
      if (backdrop_[size_t(rays.pixel[size_t(r)])]) {
        g[size_t(r)] = cfg_.backdrop_weight / float(R);
        sums[3] += acc[size_t(r)];
        sums[4] += 1;
      }
    dacc = Tensor::from_host(g, {n}, "backdrop opacity gradient");
  }
  // The distortion term: weight * mean over the batch of each ray's distortion (distances over the box's
  // diagonal), its gradient w.r.t. every sample's weight.
  Tensor dweights;
  if (cfg_.distortion_weight > 0 && cache.samples.count > 0) {
    const auto side = model_.geo.box_size();
    const float diag = std::sqrt(side[0] * side[0] + side[1] * side[1] + side[2] * side[2]);
    const render::Distortion dist = render::distortion_forward_backward(
        cache.samples, cache.weights.w, 1.0f / diag, model_.geo.step / diag, cfg_.distortion_weight / float(R));
    sums[5] += double(nn::sum(dist.loss).to_host()[0]);
    dweights = dist.dw;
  }
  const float slice_mse = nn::mse_forward(out.value, target).to_host()[0];
  sums[0] += double(slice_mse) * double(n) / double(R);
  sums[1] += double(out.samples);
  sums[2] += double(out.kept);
  // The data term's gradient, a mean over the whole batch, through the renderer.
  model_.render_backward(cache, nn::mse_backward(out.value, target, float(double(n) / double(R))), dacc, dweights);
}

StepStats DensityTrainer::step(bool with_reg) {
  const auto t0 = std::chrono::steady_clock::now();
  StepStats st;
  const int k = iteration_ + 1;
  // The batch in batch_slices slices, dealt round robin over the ranks: every rank draws the whole batch
  // (the same stream) and renders its slices, with the jitter the whole batch draws for those rays. One
  // slice in one process: the batch at once. Otherwise each slice's gradients are taken off the device and
  // summed over the slices and the ranks (lib/train/data_parallel.hpp).
  host::Dist& dist = host::Dist::world();
  const int64_t R = cfg_.batch;
  const int S = cfg_.batch_slices;
  const bool batched = S > 1 || dist.size() > 1;
  const scene::Rays batch = sampler_->next(cfg_.batch);
  model_.zero_grad();
  GradientSum grads;
  std::vector<double> sums(6, 0.0);  // mse, samples, kept, backdrop opacity, backdrop rays, distortion
  for (int j = 0; j < S; ++j) {
    if (!my_share(j, dist)) continue;
    const int64_t lo = R * j / S;
    slice_terms(batch, lo, R * (j + 1) / S - lo, k, sums);
    if (batched) grads.add(model_.params());
  }
  if (batched) {
    dist.allreduce_sum(sums);
    sync_.add(grads.average(model_.params(), 1.0, dist));  // the slices' terms add up
  }
  const double mse = sums[0];
  st.samples = int64_t(sums[1]);
  st.kept = int64_t(sums[2]);
  st.backdrop_rays = int64_t(sums[4]);
  st.backdrop_acc = st.backdrop_rays ? sums[3] / double(st.backdrop_rays) : 0.0;
  st.distortion = sums[5];
  if (!std::isfinite(mse))
    throw Error("train-density: the loss is " + std::to_string(mse) + " at iteration " + std::to_string(k) +
                " (diverged; try a lower --lr-grid or another --seed)");
  st.mse = mse;
  st.psnr = -10.0 * std::log10(std::max(mse, 1e-12));

  // The regularisers, straight into the grid gradients (after the sum: every rank adds the same terms once).
  Tensor& ddensity = model_.density_param().grad_buffer();
  Tensor& dapp = model_.rgb.app_param().grad_buffer();
  const field::VMGrid app = model_.rgb.app();
  const float reg_scale = cfg_.schedule.reg_scale(k);
  // TensoRF: TV_loss_* = sum_planes TVLoss(plane) * 1e-2 with TVLoss = 2 (mean_h + mean_w).
  const float tvd = cfg_.tv_density * reg_scale * 2e-2f, tva = cfg_.tv_app * reg_scale * 2e-2f;
  const field::VMGrid& density = model_.geo.density;
  if (l1_weight_ > 0) field::l1_backward(density, l1_weight_, ddensity);
  if (tvd > 0) field::tv_backward(density, tvd, ddensity);
  if (tva > 0) field::tv_backward(app, tva, dapp);
  if (with_reg) {
    st.reg = 0;
    if (l1_weight_ > 0) st.reg += l1_weight_ * field::l1_forward(density);
    if (tvd > 0) st.reg += tvd * field::tv_forward(density);
    if (tva > 0) st.reg += tva * field::tv_forward(app);
    st.reg += cfg_.backdrop_weight * st.backdrop_acc * st.backdrop_rays / double(R);
    st.reg += st.distortion;
  }

  adam_.step(model_.params(), cfg_.schedule.lr_scale(k));
  iteration_ = k;
  st.iteration = k;
  if (cfg_.finite_check_every > 0 && k % cfg_.finite_check_every == 0) check_finite("after iteration " + std::to_string(k));
  on_step_done(st);
  st.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return st;
}

void DensityTrainer::on_step_done(StepStats& st) {
  const int k = iteration_;
  const Schedule& s = cfg_.schedule;
  if (cfg_.alpha_mask && s.mask_at_step(k)) {
    // TensoRF: the mask at the grid resolution while that stays under 256^3 voxels.
    const auto r = model_.res();
    const int64_t voxels = int64_t(r[0]) * r[1] * r[2];
    const auto mres = voxels < 256LL * 256 * 256 ? r : res_for(model_.geo, 256LL * 256 * 256);
    model_.update_alpha_mask(mres);
    std::ostringstream e;
    e << "alpha mask " << mres[0] << "x" << mres[1] << "x" << mres[2] << ": "
      << 100.0 * double(model_.geo.mask.occupied) / (double(mres[0]) * mres[1] * mres[2]) << "% occupied";
    if (s.first_mask_step(k)) {
      l1_weight_ = cfg_.l1_rest;
      if (model_.geo.mask.empty()) {
        e << " (empty: box kept, mask not used)";
        model_.geo.mask = field::AlphaMask{};
      } else {
        // Shrink the box to the occupied region; the Adam moments follow the grids by the same crop.
        const model::GridCrop c = model_.occupied_crop();
        carry_moments(c, [&] { model_.apply_crop(c); });
        const auto nr = model_.res();
        const model::Geometry& g = model_.geo;
        e << "; box shrunk to [" << g.box_lo[0] << ", " << g.box_lo[1] << ", " << g.box_lo[2] << "] .. ["
          << g.box_hi[0] << ", " << g.box_hi[1] << ", " << g.box_hi[2] << "], grid " << nr[0] << "x"
          << nr[1] << "x" << nr[2];
        // The mask was built over the old box: rebuild it over the new one.
        const int64_t nv = int64_t(nr[0]) * nr[1] * nr[2];
        model_.update_alpha_mask(nv < 256LL * 256 * 256 ? nr : res_for(model_.geo, 256LL * 256 * 256));
      }
    } else if (model_.geo.mask.empty()) {
      e << " (empty: not used)";
      model_.geo.mask = field::AlphaMask{};
    }
    st.events.push_back(e.str());
  }
  if (s.upsample_at_step(k)) {
    const auto list = s.voxel_list();
    size_t idx = 0;
    while (s.upsample_at[idx] != k) ++idx;
    const auto nr = res_for(model_.geo, list[idx]);
    if (cfg_.reset_optimizer_on_upsample) {
      model_.upsample(nr);
      init_optimizer();  // TensoRF builds a new Adam here
    } else {
      model::GridCrop c;  // the whole box at the new resolution: the moments are upsampled with the grids
      c.res = nr;
      carry_moments(c, [&] { model_.upsample(nr); });
    }
    std::ostringstream e;
    e << "upsampled to " << nr[0] << "x" << nr[1] << "x" << nr[2] << " (" << model_.geo.max_samples << " samples/ray max)"
      << (cfg_.reset_optimizer_on_upsample ? ", optimiser reset" : "");
    st.events.push_back(e.str());
  }
}

void DensityTrainer::carry_moments(const model::GridCrop& c, const std::function<void()>& change) {
  const field::VMGrid old_density = model_.geo.density, old_app = model_.rgb.app();
  change();
  adam_.remap("density", [&](const Tensor& t) { return model::crop_like_grid(old_density, t, c); });
  adam_.remap("app", [&](const Tensor& t) { return model::crop_like_grid(old_app, t, c); });
}

void DensityTrainer::check_finite(const std::string& when) {
  const std::string bad = model_.first_nonfinite();
  if (!bad.empty())
    throw Error("train-density: parameter '" + bad + "' holds NaN or infinite values " + when +
                " (diverged; try a lower --lr-grid or another --seed)");
}

void DensityTrainer::save(const std::string& path, const json& scene_meta) {
  check_finite("at iteration " + std::to_string(iteration_) + "; checkpoint " + path + " not written");
  io::Checkpoint ck;
  ck.kind = "density";
  model::save_model(ck, model_);
  ck.meta["scene"] = scene_meta;
  ck.meta["trainer"] = {{"config", cfg_.to_json()},
                        {"iteration", iteration_},
                        {"l1_weight", l1_weight_}};
  adam_.save(ck, "");
  io::save_checkpoint(path, ck);
}

// ---- evaluation --------------------------------------------------------------------------------------------
std::vector<ViewScore> evaluate_views(const model::DensityModel& m, const scene::Scene& scene, int max_views, bool ssim) {
  const int n = static_cast<int>(scene.test.size());
  std::vector<int> ids;
  if (max_views <= 0 || max_views >= n) {
    for (int i = 0; i < n; ++i) ids.push_back(i);
  } else {
    for (int i = 0; i < max_views; ++i) ids.push_back(static_cast<int>(int64_t(i) * n / max_views));
  }
  std::vector<ViewScore> out;
  for (int id : ids) {
    const scene::View& v = scene.test[size_t(id)];
    if (v.rgb.empty()) throw Error("evaluate: test view " + v.image_path + " has no image loaded");
    const model::ViewValues r = model::render_view(m, scene, v.camera);
    ViewScore s;
    s.view = id;
    s.psnr = eval::psnr(r.value, v.rgb);
    if (ssim)
      s.ssim =
          eval::ssim(eval::interleaved_to_planar(r.value, r.width, r.height), eval::interleaved_to_planar(v.rgb, r.width, r.height), r.width, r.height, 3);
    const auto backdrop = scene::backdrop_pixels(scene, v);
    double sum = 0;
    size_t count = 0;
    for (size_t i = 0; i < backdrop.size(); ++i)
      if (backdrop[i]) sum += r.acc[i], ++count;
    if (count > 0) s.backdrop_acc = sum / double(count);
    out.push_back(s);
  }
  return out;
}

double mean_backdrop_acc(const std::vector<ViewScore>& v) {
  double s = 0;
  int n = 0;
  for (const auto& x : v)
    if (x.backdrop_acc >= 0) s += x.backdrop_acc, ++n;
  return n ? s / n : -1.0;
}

double mean_psnr(const std::vector<ViewScore>& v) {
  double s = 0;
  for (const auto& x : v) s += x.psnr;
  return v.empty() ? 0.0 : s / double(v.size());
}

}  // namespace stylerf::train

namespace stylerf::train {

namespace {

// The density stage in the training loop: the window's loss, batch PSNR and samples a ray.
class DensityLoopStage : public TrainerLoopStage<DensityTrainer, RunOptions, StepStats> {
 public:
  DensityLoopStage(DensityTrainer& t, const RunOptions& o) : TrainerLoopStage(t, o) {}
  int total() const override { return t_.config().schedule.iters; }
  void step(bool report) override {
    last_ = t_.step(report);
    psnr_ += last_.psnr, mse_ += last_.mse, samples_ += last_.samples, kept_ += last_.kept, ++n_;
    backdrop_acc_ += last_.backdrop_acc * last_.backdrop_rays, backdrop_rays_ += last_.backdrop_rays;
    if (o_.log)
      for (const auto& e : last_.events) *o_.log << "  [" << last_.iteration << "] " << e << std::endl;
  }
  std::string window_line(double per_it) override {
    const int batch = t_.config().batch;
    std::ostringstream l;
    l << std::fixed << std::setprecision(4) << "  loss " << mse_ / n_ + std::max(0.0, last_.reg) << " (mse "
      << mse_ / n_ << ")" << std::setprecision(2) << "  psnr " << psnr_ / n_ << "  samples/ray "
      << std::setprecision(1) << double(samples_) / (double(n_) * batch) << " (kept "
      << 100.0 * double(kept_) / std::max<double>(1.0, double(samples_)) << "%)  " << std::setprecision(0)
      << batch / per_it << " rays/s";
    if (backdrop_rays_ > 0)
      l << std::setprecision(4) << "  backdrop opacity " << backdrop_acc_ / double(backdrop_rays_);
    backdrop_acc_ = 0;
    backdrop_rays_ = 0;
    last_psnr = psnr_ / n_;
    psnr_ = mse_ = 0;
    samples_ = kept_ = 0;
    n_ = 0;
    return l.str();
  }
  void refit(const Refit& r) override {
    if (!o_.fit_schedule_to_budget || r.total_iters == total()) return;
    t_.refit_schedule(r.total_iters);
    if (o_.log)
      *o_.log << "  [" << t_.iteration() << "] " << std::fixed << std::setprecision(2) << r.seconds_per_step << " s/it -> "
              << r.total_iters << " iterations fit the budget: " << t_.config().schedule.describe() << std::endl;
  }
  void save() override {
    if (!o_.checkpoint.empty()) t_.save(o_.checkpoint, o_.scene_meta);
  }
  void end_of_run() override {
    if (n_) last_psnr = psnr_ / n_;
  }
  double last_psnr = 0;

 private:
  double psnr_ = 0, mse_ = 0, backdrop_acc_ = 0;
  int64_t backdrop_rays_ = 0;
  int64_t samples_ = 0, kept_ = 0;
  int n_ = 0;
};

}  // namespace

RunSummary run_density_training(DensityTrainer& trainer, const RunOptions& opt) {
  DensityLoopStage stage(trainer, opt);
  const LoopResult r = run_training_loop(stage, loop_control(opt, density_stage_programs(trainer.model())));
  return {r.iterations, r.seconds, stage.last_psnr};
}

}  // namespace stylerf::train
