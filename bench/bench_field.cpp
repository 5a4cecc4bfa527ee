// `stylerf bench field`: see bench_field.hpp. Sizes follow training: 4096 rays through a box with a
// 300^3 grid (quick: 512 rays, 128^3), step half a voxel (~600 candidate samples per ray), density rank
// [16,4,4], appearance rank [48,12,12]. Points for grid sampling are the marched samples (ray order, as in
// training), not uniform random points. STYLERF_BENCH_FILTER=part,part times only the rows whose names
// contain one of the parts (rows whose results later rows need still run once, untimed).
#include "bench/bench_field.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <iostream>
#include <nlohmann/json.hpp>
#include <random>
#include <vector>

#include "bench/random_fill.hpp"
#include "host/files.hpp"
#include "host/runtime.hpp"
#include "host/tensor.hpp"
#include "lib/field/alpha_mask.hpp"
#include "lib/field/appearance_head.hpp"
#include "lib/field/vm_grid.hpp"
#include "lib/render/composite.hpp"
#include "lib/render/composite_values.hpp"
#include "lib/render/deferred.hpp"
#include "lib/render/distortion.hpp"
#include "lib/render/weights.hpp"
#include "lib/render/ray_march.hpp"

namespace stylerf::bench {

using host::Tensor;

namespace {

// Best wall time in ms over `repeats` runs after one warm-up (each run ends with a queue finish).
double best_ms(int repeats, const std::function<void()>& f) {
  auto& rt = host::Runtime::instance();
  f();
  rt.finish();
  double best = 1e30;
  for (int i = 0; i < repeats; ++i) {
    auto t0 = std::chrono::steady_clock::now();
    f();
    rt.finish();
    best = std::min(best, std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
  return best;
}

// Camera-like rays: origins on a sphere of radius 4 around the box, aimed at random points in [-1,1]^3.
void make_rays(int R, std::vector<float>& o, std::vector<float>& d) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  for (int i = 0; i < R; ++i) {
    float a[3] = {u(rng), u(rng), u(rng)};
    const float l = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]) + 1e-6f;
    float org[3], dir[3], dl = 0;
    for (int k = 0; k < 3; ++k) org[k] = 4.0f * a[k] / l;
    for (int k = 0; k < 3; ++k) dir[k] = u(rng) - org[k], dl += dir[k] * dir[k];
    for (int k = 0; k < 3; ++k) o.push_back(org[k]), d.push_back(dir[k] / std::sqrt(dl));
  }
}

struct Row {
  std::string name;
  double ms, rate, gbs;
  std::string unit;
};

}  // namespace

int bench_field(const BenchOptions& opt) {
  auto& rt = host::Runtime::instance();
  const int repeats = opt.quick ? 1 : opt.repeats;
  const int R = opt.quick ? 512 : 4096, G = opt.quick ? 128 : 300;
  std::cout << "device: " << rt.device().describe() << "\n"
            << "field kernels: " << R << " rays, grid " << G << "^3, best of " << repeats << " after a warm-up\n";
  std::vector<Row> rows;
  // STYLERF_BENCH_FILTER=a,b: time only rows whose name contains one of the comma-separated parts.
  const char* filter_env = std::getenv("STYLERF_BENCH_FILTER");
  const std::string filter = filter_env ? filter_env : "";
  auto want = [&](const std::string& name) {
    if (filter.empty()) return true;
    size_t b = 0;
    while (b <= filter.size()) {
      size_t e = filter.find(',', b);
      if (e == std::string::npos) e = filter.size();
      if (e > b && name.find(filter.substr(b, e - b)) != std::string::npos) return true;
      b = e + 1;
    }
    return false;
  };
  // Times f unless the row is filtered out; a filtered row still runs once when later rows need its result.
  auto timed = [&](const std::string& name, bool needed, const std::function<void()>& f) {
    if (want(name)) return best_ms(repeats, f);
    if (needed) {
      f();
      rt.finish();
    }
    return -1.0;
  };
  auto add = [&](const std::string& name, double ms, double items, const std::string& unit, double bytes) {
    if (ms < 0) return;  // filtered out
    rows.push_back({name, ms, items / (ms * 1e3), bytes / (ms * 1e6), unit});
    std::printf("%-34s %10.2f ms %10.2f %-8s %8.2f GB/s\n", name.c_str(), ms, items / (ms * 1e3), unit.c_str(),
                bytes / (ms * 1e6));
    std::fflush(stdout);
  };

  // ---- ray marching ----------------------------------------------------------------------------------
  render::MarchConfig mc;
  mc.box_lo = {-1.5f, -1.5f, -1.5f};
  mc.box_hi = {1.5f, 1.5f, 1.5f};
  mc.near = 0.0f;
  mc.far = 100.0f;
  mc.step = render::step_for_grid(mc.box_lo, mc.box_hi, {G, G, G}, 0.5f);
  mc.max_samples = render::max_samples_for_grid(mc.box_lo, mc.box_hi, mc.step);
  mc.jitter = true;
  std::vector<float> o, d;
  make_rays(R, o, d);
  Tensor to = Tensor::from_host(o, {R, 3}), td = Tensor::from_host(d, {R, 3});
  render::Samples s;
  double ms = timed("march (no mask)", true, [&] { s = render::march(to, td, mc, nullptr); });
  std::printf("samples: %lld (%.0f per ray), step %.5f\n", (long long)s.count, double(s.count) / R, mc.step);
  add("march (no mask)", ms, R, "Mrays/s", double(s.count) * 24 + R * 32.0);

  // A mask with a ball of radius 0.8 (of the half-size 1.5) occupied, at half the grid resolution.
  field::VMGrid dens = field::VMGrid::create({G, G, G}, {16, 4, 4}, 0.1f, 1);
  const int M = G / 2;
  {
    field::AlphaMask mask;
    ms = timed("alpha mask build (" + std::to_string(M) + "^3)", false, [&] {
      mask = field::build_alpha_mask(dens, field::DensityActivation::Relu, {M, M, M}, mc.step, 1e-4f);
    });
    add("alpha mask build (" + std::to_string(M) + "^3)", ms, double(M) * M * M, "Mvox/s", double(M) * M * M * 2);
  }
  std::vector<uint8_t> ball(size_t(M) * M * M);
  for (int z = 0; z < M; ++z)
    for (int y = 0; y < M; ++y)
      for (int x = 0; x < M; ++x) {
        auto c = [&](int i) { return -1.0 + (2.0 * i + 1) / M; };
        ball[(size_t(z) * M + y) * M + x] = c(x) * c(x) + c(y) * c(y) + c(z) * c(z) < 0.8 * 0.8 / (1.5 * 1.5) * 2.25;
      }
  field::AlphaMask mask;
  mask.res = {M, M, M};
  mask.voxels = Tensor::from_host(ball, {M, M, M}, "bench mask");
  render::Samples sm;
  ms = timed("march (ball mask)", true, [&] { sm = render::march(to, td, mc, &mask); });
  std::printf("samples with mask: %lld (%.0f per ray)\n", (long long)sm.count, double(sm.count) / R);
  add("march (ball mask)", ms, R, "Mrays/s", double(sm.count) * 24 + R * 32.0);

  // ---- grid sampling ---------------------------------------------------------------------------------
  const int64_t N = s.count;
  const Tensor& pts = s.positions;
  const double pts_bytes = double(N) * 12;
  {
    const double taps = double(N) * 6 * 24 * 4;  // 6 taps per mode, rank 16+4+4, floats gathered
    Tensor sigma;
    ms = timed("density fwd (rank 16,4,4)", false, [&] { sigma = field::density_forward(dens, pts, field::DensityActivation::Relu); });
    add("density fwd (rank 16,4,4)", ms, double(N), "Mpts/s", pts_bytes + N * 4.0 + taps);
    Tensor dsig = Tensor::full({N}, 1e-3f);
    Tensor dgrid = Tensor::zeros(dens.params.shape());
    // Softplus so every point has a gradient (relu of a random grid zeroes about half).
    Tensor sp = field::density_forward(dens, pts, field::DensityActivation::Softplus);
    ms = timed("density bwd private", false, [&] {
      field::density_backward(dens, pts, sp, dsig, dgrid, field::DensityActivation::Softplus,
                              field::ScatterMode::Private);
    });
    add("density bwd private", ms, double(N), "Mpts/s", pts_bytes + N * 8.0 + 2 * taps);
    // The fixed-point scatter also reads dsig and the grid once more for its scale bound.
    ms = timed("density bwd fixed", false, [&] {
      field::density_backward(dens, pts, sp, dsig, dgrid, field::DensityActivation::Softplus,
                              field::ScatterMode::Fixed);
    });
    add("density bwd fixed", ms, double(N), "Mpts/s", pts_bytes + N * 12.0 + 2 * taps + dens.numel() * 20.0);

    // Early ray termination: the march evaluates the density as it goes (kernels/march_density.cl). On
    // this thin random grid no ray stops, so the row is the march + density pair above fused; on a dense
    // grid (every value + 0.5) rays stop early and the row shows the saving. Per ray, and GB/s of the
    // samples written and the taps read up to the stops.
    for (bool dense : {false, true}) {
      field::VMGrid g = dens;
      if (dense) {
        g = field::VMGrid::create({G, G, G}, {16, 4, 4}, 0.1f, 1);
        auto v = g.params.to_host();
        for (auto& x : v) x += 0.5f;
        g.params.upload(v);
      }
      render::DensityMarch dm{&g, field::DensityActivation::Relu, 1e-4f};
      render::Samples se;
      const std::string name = dense ? "march+density ERT (dense: stops)" : "march+density ERT (thin: no stop)";
      ms = timed(name, false, [&] { se = render::march(to, td, mc, nullptr, &dm); });
      if (ms >= 0)
        std::printf("samples with early termination: %lld (%.0f per ray)\n", (long long)se.count,
                    double(se.count) / R);
      add(name, ms, R, "Mrays/s", double(se.count) * (28 + 6 * 24 * 4) + R * 32.0);
    }
  }
  const int64_t Nm = sm.count;  // appearance runs on the (masked, compacted) samples, as in training
  {
    field::VMGrid app = field::VMGrid::create({G, G, G}, {48, 12, 12}, 0.1f, 2);
    const double taps = double(Nm) * 6 * 72 * 4;
    Tensor feat;
    ms = timed("app features fwd (rank 48,12,12)", want("head "), [&] { feat = field::features_forward(app, sm.positions); });
    add("app features fwd (rank 48,12,12)", ms, double(Nm), "Mpts/s", Nm * 12.0 + Nm * 72 * 4.0 + taps);
    Tensor dfeat = Tensor::full({Nm, 72}, 1e-3f);
    Tensor dgrid = Tensor::zeros(app.params.shape());
    ms = timed("app features bwd private", false, [&] { field::features_backward(app, sm.positions, dfeat, dgrid, field::ScatterMode::Private); });
    add("app features bwd private", ms, double(Nm), "Mpts/s", Nm * 12.0 + Nm * 72 * 4.0 + 2 * taps);
    ms = timed("app features bwd fixed", false, [&] { field::features_backward(app, sm.positions, dfeat, dgrid, field::ScatterMode::Fixed); });
    add("app features bwd fixed", ms, double(Nm), "Mpts/s", Nm * 12.0 + Nm * 72 * 8.0 + 2 * taps + app.numel() * 20.0);
    ms = timed("TV bwd (appearance planes)", false, [&] { field::tv_backward(app, 1.0f, dgrid); });
    add("TV bwd (appearance planes)", ms, double(app.numel()), "Mparam/s", app.numel() * 12.0);

    field::AppearanceHead head = field::AppearanceHead::create(field::AppearanceHeadConfig{}, 3);
    field::HeadCache cache;
    ms = timed("head fwd (GFLOP/s in GB/s col)", want("head bwd"), [&] { field::appearance_forward(head, feat, Tensor(), &cache); });
    const double flop = 2.0 * Nm * (72 * 27 + 27 * 128 + 128 * 128 + 128 * 3);
    add("head fwd (GFLOP/s in GB/s col)", ms, double(Nm), "Mpts/s", flop / 1e0);
    Tensor drgb = Tensor::full({Nm, 3}, 1e-3f);
    ms = timed("head bwd (GFLOP/s in GB/s col)", false, [&] { field::appearance_backward(head, cache, drgb); });
    add("head bwd (GFLOP/s in GB/s col)", ms, double(Nm), "Mpts/s", 2 * flop);
  }

  // ---- compositing ------------------------------------------------------------------------------------
  {
    Tensor sigma = Tensor::from_host(normal_floats(size_t(N), 4, 2.0f), {N});
    Tensor rgb = Tensor::full({N, 3}, 0.5f);
    Tensor bg = Tensor::full({3}, 1.0f);
    render::Weights wt;
    ms = timed("weights fwd (sigma -> w)", true, [&] { wt = render::weights_forward(s, sigma); });
    add("weights fwd (sigma -> w)", ms, double(N), "Msmp/s", N * (4.0 + 4 + 4 + 4) + R * 16.0);
    Tensor dw = Tensor::full({N}, 1e-3f), da = Tensor::full({R}, 1.0f);
    ms = timed("weights bwd (dw -> dsigma)", false, [&] { render::weights_backward(s, sigma, dw, da, Tensor()); });
    add("weights bwd (dw -> dsigma)", ms, double(N), "Msmp/s", N * 2 * (4.0 + 4 + 4 + 4) + N * 4.0);
    // The density stage's distortion term: two passes over w and t, dw written.
    ms = timed("distortion fwd+bwd (w -> dw)", false,
               [&] { render::distortion_forward_backward(s, wt.w, 0.5f, 0.005f, 1e-3f); });
    add("distortion fwd+bwd (w -> dw)", ms, double(N), "Msmp/s", N * (2 * (4.0 + 4) + 4) + R * 12.0);
    render::Kept k;
    ms = timed("keep_by_weight", true, [&] { k = render::keep_by_weight(s, wt.w, 1e-4f); });
    add("keep_by_weight", ms, double(N), "Msmp/s", N * 4.0 * 2 + k.count * 4.0);
    render::KeptLayout layout;
    layout.count = k.count;
    layout.ray_offset = k.ray_offset;
    layout.ray_count = k.ray_count;
    layout.ray_index = render::gather_rows(s.ray_index, k.index, k.count);
    Tensor kw = render::gather_rows(wt.w, k.index, k.count);
    const double K = double(k.count);
    // The weighted sum over kept samples at the stage-1 (3) and stage-2/3 (256, 144) channel counts.
    for (int C : {3, 144, 256}) {
      Tensor vals = Tensor::full({k.count, C}, 0.5f);
      const std::string fwd = "values fwd C=" + std::to_string(C), bwd = "values bwd C=" + std::to_string(C);
      render::CompositedValues cv;
      ms = timed(fwd, false, [&] { cv = render::composite_values_forward(layout, kw, vals); });
      add(fwd, ms, K, "Msmp/s", K * (4.0 + 4.0 * C) + R * 4.0 * (C + 1));
      Tensor dout = Tensor::full({R, C}, 1e-3f);
      ms = timed(bwd, false, [&] { render::composite_values_backward(layout, kw, vals, dout, Tensor()); });
      add(bwd, ms, K, "Msmp/s", K * (4.0 + 3 * 4.0 * C + 8) + R * 4.0 * C);
    }
    // The grouped renderer's merge: each entry's row read through an index (here the kept list reversed,
    // at the field components' 72 channels), against the same sum over rows gathered first.
    {
      const int C = 72;
      std::vector<int32_t> rev(size_t(k.count));
      for (int64_t i = 0; i < k.count; ++i) rev[size_t(i)] = int32_t(k.count - 1 - i);
      Tensor rows = Tensor::from_host(rev, {k.count}), vals = Tensor::full({k.count, C}, 0.5f);
      const std::string fwd = "values fwd indexed C=72";
      ms = timed(fwd, false, [&] { render::composite_values_forward(layout, kw, vals, rows); });
      add(fwd, ms, K, "Msmp/s", K * (8.0 + 4.0 * C) + R * 4.0 * (C + 1));
      const std::string gfwd = "gather + values fwd C=72";
      ms = timed(gfwd, false, [&] { render::composite_values_forward(layout, kw, render::gather_rows(vals, rows, k.count)); });
      add(gfwd, ms, K, "Msmp/s", K * (8.0 + 3 * 4.0 * C) + R * 4.0 * (C + 1));
    }
  }

  // ---- deferred shading's per-ray ops (lib/render/deferred.hpp), at the appearance features' 72 channels ----
  {
    const int C = 72;
    Tensor F = Tensor::full({R, C}, 0.25f), a = Tensor::full({R}, 0.5f), g = Tensor::full({R, C}, 1e-3f);
    Tensor da = Tensor::zeros({R});
    const double rc = double(R) * C;
    ms = timed("deferred normalise fwd C=72", false, [&] { render::opacity_normalise_forward(F, a); });
    add("deferred normalise fwd C=72", ms, R, "Mrays/s", rc * 8.0 + R * 4.0);
    ms = timed("deferred normalise bwd C=72", false, [&] { render::opacity_normalise_backward(F, a, g, da); });
    add("deferred normalise bwd C=72", ms, R, "Mrays/s", rc * 12.0 + R * 12.0);
    ms = timed("deferred scale fwd C=72", false, [&] { render::opacity_scale_forward(F, a); });
    add("deferred scale fwd C=72", ms, R, "Mrays/s", rc * 8.0 + R * 4.0);
    ms = timed("deferred scale bwd C=72", false, [&] { render::opacity_scale_backward(F, a, g, da); });
    add("deferred scale bwd C=72", ms, R, "Mrays/s", rc * 12.0 + R * 12.0);
  }

  if (!opt.json_path.empty()) {
    nlohmann::json j = {{"bench", "field"}, {"device", rt.device().describe()}, {"rays", R}, {"grid", G},
                        {"samples", N}, {"samples_masked", Nm}, {"repeats", repeats}};
    for (auto& r : rows)
      j["rows"].push_back({{"name", r.name}, {"ms", r.ms}, {"rate", r.rate}, {"unit", r.unit}, {"gb_s", r.gbs}});
    host::write_file_atomic(opt.json_path, j.dump(2) + "\n");
    std::cout << "wrote " << opt.json_path << "\n";
  }
  return 0;
}

}  // namespace stylerf::bench
