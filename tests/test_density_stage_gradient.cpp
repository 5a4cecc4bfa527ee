// The density stage's loss end to end, on the generated scene (its images have alpha: the background colour
// is composited behind each ray, and the backdrop term watches the transparent pixels):
//  - wiring: the test's copy of a training step (DensityTrainer::step's calls, the trainer's rays, jitter and
//    regulariser weights) gives the loss the trainer reports (mse + reg);
//  - the gradient the trainer's step left in the parameters (before Adam moved them) against central
//    differences of that loss along random directions: over every parameter, and per block (the density grid,
//    the appearance grid, each layer of the appearance MLP), with deferred shading (the default) and per
//    sample (TensoRF's); TV, L1 and the distortion term on, so every regulariser's gradient is in the sum
//    (the distortion written here as its double sum over each ray's sample pairs);
//  - a few dozen steps lower the loss.
// Measured on the 2-core CPU (PoCL): the loss is ~0.1, float32 on the device (summed in double here); gaps are in units of the block's spread (the
// standard deviation of g . d over random directions, tests/stage_gradient.hpp), worst measured in brackets.
#include <doctest/doctest.h>

#include <cmath>
#include <functional>
#include <string>
#include <memory>
#include <vector>

#include "lib/io/checkpoint.hpp"
#include "lib/scene/masked_background.hpp"
#include "lib/train/density_trainer.hpp"
#include "tests/small_scene.hpp"
#include "tests/stage_gradient.hpp"
#include "tests/testing.hpp"

using namespace stylerf;
using host::Tensor;

namespace {

// Relative steps. The density grid (and the sum over every parameter, which it dominates) crosses the relu's
// kinks: gap 0.04 at 1e-3, 0.034 at 3e-4, 0.021 at 1e-4, 0.001 .. 0.012 at 3e-5, 0.05 at 1e-5 (rounding).
// The appearance grid and the MLP move the loss of ~0.1 by too little for float32 below ~1e-2 (head.basis:
// gap 0.4 at 3e-4, 0.055 at 1e-2, 0.019 at 3e-2) and are smooth there.
constexpr double kDensityStep = 1e-4;
constexpr double kAppearanceStep = 3e-2;
constexpr double kTol = 0.1;

constexpr int kWarmSteps = 30;  // steps before the checked one: a density that is neither empty nor opaque

train::DensityTrainConfig small_config(bool deferred, field::DensityActivation act) {
  auto cfg = train::default_density_config(testing::small_scene());
  cfg.model.density_rank = {4, 4, 4};
  cfg.model.app_rank = {8, 8, 8};
  cfg.model.hidden = 32;
  cfg.model.deferred_shading = deferred;
  cfg.model.act = act;
  cfg.schedule.iters = 40;
  cfg.schedule.voxels_init = cfg.schedule.voxels_final = 24 * 24 * 24;
  cfg.schedule.upsample_at = {};  // no event: every step is the same loss
  cfg.schedule.mask_at = {};
  cfg.batch = 256;
  cfg.tv_density = 1.0f;  // Blender's config has no TV: switched on so that its gradient is checked too
  cfg.tv_app = 1.0f;
  cfg.distortion_weight = 2.0f;  // on for captures with a shell only: here on, and heavy enough to show in the sum
  cfg.seed = 5;
  return cfg;
}

// DensityTrainer::step's loss at step k (its rays: the trainer's sampler, same seed, k - 1 batches drawn
// before): MSE + L1 + TV terms + the backdrop term + the distortion term.
struct StepLoss {
  const scene::Scene* scene = nullptr;
  train::DensityTrainConfig cfg;
  int k = 0;
  Tensor o, d;
  std::vector<float> rgb_target;
  std::vector<float> backdrop;  // per ray: backdrop_weight / R on backdrop rays, else 0

  StepLoss(const scene::Scene& s, const train::DensityTrainConfig& c, int step) : scene(&s), cfg(c), k(step) {
    std::vector<uint8_t> mask;
    for (const auto& v : s.train) {
      const auto m = scene::backdrop_pixels(s, v);
      mask.insert(mask.end(), m.begin(), m.end());
    }
    scene::RaySampler sampler(s, c.seed * 0x9E3779B97F4A7C15ULL);
    scene::Rays rays;
    for (int i = 0; i < k; ++i) rays = sampler.next(c.batch);
    const int64_t R = c.batch;
    o = Tensor::from_host(rays.origins, {R, 3});
    d = Tensor::from_host(rays.directions, {R, 3});
    rgb_target = rays.rgb;
    backdrop.assign(size_t(R), 0.0f);
    for (int64_t r = 0; r < R; ++r)
      if (!mask.empty() && mask[size_t(rays.pixel[size_t(r)])]) backdrop[size_t(r)] = c.backdrop_weight / float(R);
  }

  int backdrop_rays() const {
    int n = 0;
    for (float b : backdrop) n += b > 0;
    return n;
  }

  double operator()(const model::DensityModel& m) const {
    model::RayContext ctx;
    const model::RayResult out = m.render(o, d, true, uint32_t(cfg.seed * 7919 + uint64_t(k)), &ctx);
    // The MSE summed in double: the device's float32 scalar would quantise a loss of ~0.1 to steps of ~1e-8,
    // the size of a small block's change at these steps.
    const auto rgb = out.value.to_host();
    double loss = 0;
    for (size_t i = 0; i < rgb.size(); ++i) loss += (double(rgb[i]) - rgb_target[i]) * (double(rgb[i]) - rgb_target[i]);
    loss /= double(rgb.size());
    const auto acc = out.acc.to_host();
    for (size_t r = 0; r < acc.size(); ++r) loss += double(backdrop[r]) * acc[r];
    // The distortion term: weight / R x sum over rays of sum_ij w_i w_j |u_i - u_j| + d/3 sum_i w_i^2, with
    // u = t / |box diagonal| and d the march step over the same.
    if (ctx.samples.count > 0) {
      const auto w = ctx.weights.w.to_host(), t = ctx.samples.t.to_host();
      const auto off = ctx.samples.ray_offset.to_host_i32(), cnt = ctx.samples.ray_count.to_host_i32();
      double diag2 = 0;
      for (int a = 0; a < 3; ++a) diag2 += std::pow(double(m.geo.box_hi[size_t(a)]) - m.geo.box_lo[size_t(a)], 2);
      const double inv_len = 1.0 / std::sqrt(diag2), dlen = double(m.geo.step) * inv_len;
      double dist = 0;
      for (size_t r = 0; r < off.size(); ++r)
        for (int i = off[r]; i < off[r] + cnt[r]; ++i) {
          for (int j = off[r]; j < off[r] + cnt[r]; ++j)
            dist += double(w[size_t(i)]) * w[size_t(j)] * std::fabs(double(t[size_t(i)]) - t[size_t(j)]) * inv_len;
          dist += dlen / 3.0 * double(w[size_t(i)]) * w[size_t(i)];
        }
      loss += double(cfg.distortion_weight) / double(cfg.batch) * dist;
    }
    const float reg = cfg.schedule.reg_scale(k);
    loss += double(cfg.l1_initial) * field::l1_forward(m.geo.density);  // before the first mask update
    loss += double(cfg.tv_density * reg * 2e-2f) * field::tv_forward(m.geo.density);
    loss += double(cfg.tv_app * reg * 2e-2f) * field::tv_forward(m.rgb.app());
    return loss;
  }
};

// The trainer's step on `sc` against central differences of StepLoss: the whole, and the blocks `which`
// selects by name.
void check_step_gradient(const scene::Scene& sc, bool deferred, bool backdrop,
                         const std::function<bool(const std::string&)>& which) {
  CAPTURE(deferred);
  // relu (StyleRF's configs): opaque from the start. TensoRF's shifted softplus leaves the density ~0 for
  // the first dozens of steps, and its gradient below float32's resolution of the loss.
  const auto cfg = small_config(deferred, field::DensityActivation::Relu);
  train::DensityTrainer t(sc, cfg);
  // Every sample kept and none cut by early termination: both thresholds make the loss jump where a
  // sample's weight or a ray's transmittance crosses them (measured: gaps of 0.13 .. 0.37 at steps
  // 3e-4 .. 1e-4, from jumps of ~1e-7), and no gradient describes a jump.
  t.model().geo.weight_threshold = 0.0f;
  t.model().geo.ert_threshold = 0.0f;
  for (int i = 0; i < kWarmSteps; ++i) t.step();
  model::DensityModel& m = t.model();
  const StepLoss loss(sc, cfg, kWarmSteps + 1);
  CHECK((loss.backdrop_rays() > 0) == backdrop);

  // The trainer's step: its reported loss, and the gradient it left (Adam has moved the weights since).
  const testing::ParamPoint at(m.params());
  const double before = loss(m);
  const train::StepStats st = t.step(true);
  const auto grad = at.grads();
  at.restore();
  CHECK(loss(m) == before);  // put back exactly
  CHECK(st.mse + st.reg == doctest::Approx(before).epsilon(1e-5));  // the copy is the trainer's loss (wiring)

  auto L = [&] { return loss(m); };
  const testing::ParamFilter all = [](const nn::Param&) { return true; };
  testing::check_directional("all parameters",
                             testing::directional(at, grad, at.direction(all, 10), kDensityStep, at.spread(grad, all), L), kTol);
  uint64_t seed = 20;
  // The grids whole (and the background shell's map, where there is one); the MLP's tensors (head.basis,
  // head.w1, ...) each alone.
  for (const auto& [block, sel] : at.blocks([](const nn::Param& p) { return p.name.rfind("head.", 0) == 0; })) {
    if (!which(block)) continue;
    const double spread = at.spread(grad, sel);
    CHECK_MESSAGE(spread > 0, block << " gets no gradient");
    testing::check_directional(
        block, testing::directional(at, grad, at.direction(sel, seed++), block == "density" ? kDensityStep : kAppearanceStep, spread, L),
        kTol);
  }
}

}  // namespace

TEST_CASE("density stage: the step's gradient matches central differences, over all parameters and per block") {
  const scene::Scene& sc = testing::small_scene();
  REQUIRE(sc.effects.background);
  for (const bool deferred : {true, false}) check_step_gradient(sc, deferred, true, [](const std::string&) { return true; });
}

TEST_CASE("density stage with a background shell: the step's gradient, the shell's map included, matches central "
          "differences") {
  // The generated scene as a capture with real surroundings: rays leaving the box see the shell's map,
  // which learns the white the images show there.
  scene::Scene sc = testing::small_scene();
  sc.effects.background = false;
  sc.effects.background_shell = true;
  sc.shell_radius = 4.0f;
  // The shell's map as a block of its own; the other blocks are the case above's (here the MLP's share of
  // the loss falls below float32's resolution: g.d ~1e-10).
  for (const bool deferred : {true, false})
    check_step_gradient(sc, deferred, false, [](const std::string& block) { return block == "background_shell"; });
  train::DensityTrainer t(sc, small_config(true, field::DensityActivation::Relu));
  REQUIRE(t.model().geo.shell.on());
  bool has_map = false;
  for (nn::Param* p : t.model().params()) has_map |= p->name == "background_shell";
  CHECK(has_map);

  // A checkpoint keeps the shell and its map: the same rays render bit-identically after loading.
  for (int i = 0; i < 5; ++i) t.step();
  const testing::TempDir dir("density_stage_gradient", "shell");
  t.save(dir.str("shell.ckpt"), nlohmann::json{{"dir", "x"}});
  const model::DensityModel loaded = model::load_model(io::load_checkpoint(dir.str("shell.ckpt"), "density"));
  CHECK(loaded.geo.shell.radius == 4.0f);
  CHECK(loaded.shell_map.value.to_host() == t.model().shell_map.value.to_host());
  const StepLoss rays(sc, small_config(true, field::DensityActivation::Relu), 3);
  CHECK(loaded.render(rays.o, rays.d, false, 0, nullptr).value.to_host() ==
        t.model().render(rays.o, rays.d, false, 0, nullptr).value.to_host());
}

TEST_CASE("density stage: a few dozen steps lower the loss") {
  auto cfg = small_config(true, field::DensityActivation::Relu);
  cfg.schedule.iters = 30;
  cfg.batch = 512;
  train::DensityTrainer t(testing::small_scene(), cfg);
  std::vector<double> loss;
  while (!t.done()) {
    const auto st = t.step(true);
    loss.push_back(st.mse + st.reg);
  }
  double first = 0, last = 0;
  for (size_t i = 0; i < 5; ++i) first += loss[i] / 5, last += loss[loss.size() - 1 - i] / 5;
  INFO("loss of the first 5 steps " << first << ", of the last 5 " << last);
  CHECK(std::isfinite(first));
  CHECK(last < 0.7 * first);
}
