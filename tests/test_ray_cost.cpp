// The ray-cost cuts, each against a plain reference:
// - early ray termination (render::march with a DensityMarch, kernels/march_density.cl): each ray's samples
//   are the prefix of the plain march up to and including the first sample whose optical depth, summed in
//   double on the host from density_forward at the plain samples, exceeds -log(threshold); sigma equals
//   density_forward there. Hard cases: huge densities (one sample a ray), zero density (no stop), rays
//   missing the box, NaN grid values, and the threshold checks.
// - deferred shading's two per-ray ops (lib/render/deferred.hpp): forward vs a double reference, backward vs
//   central differences of that reference, and the empty ray (a = 0), a negative opacity, huge features.
#include <doctest/doctest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "host/error.hpp"
#include "host/tensor.hpp"
#include "lib/field/vm_grid.hpp"
#include "lib/render/deferred.hpp"
#include "lib/render/ray_march.hpp"
#include "tests/testing.hpp"

using namespace stylerf;
using host::Tensor;

namespace {

// Rays from outside the unit box through random points in it, plus one ray that misses the box.
void make_rays(int n, uint32_t seed, Tensor& o, Tensor& d) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-0.8f, 0.8f);
  std::vector<float> ov, dv;
  for (int i = 0; i < n; ++i) {
    const float origin[3] = {u(rng), u(rng) + 2.5f * (i % 2 ? 1 : -1), u(rng) - 3.0f};
    const float target[3] = {u(rng), u(rng), u(rng)};
    float dir[3], len = 0;
    for (int a = 0; a < 3; ++a) dir[a] = target[a] - origin[a], len += dir[a] * dir[a];
    for (int a = 0; a < 3; ++a) ov.push_back(origin[a]), dv.push_back(dir[a] / std::sqrt(len));
  }
  ov.insert(ov.end(), {5.0f, 5.0f, 5.0f});
  dv.insert(dv.end(), {0.0f, 0.0f, 1.0f});
  o = Tensor::from_host(ov, {n + 1, 3});
  d = Tensor::from_host(dv, {n + 1, 3});
}

render::MarchConfig config(bool jitter) {
  render::MarchConfig c;
  c.near = 0.0f;
  c.far = 10.0f;
  c.step = 0.02f;
  c.max_samples = 400;
  c.jitter = jitter;
  c.seed = 7;
  c.delta_scale = 1.0f;
  return c;
}

// A grid whose relu density is mean_offset + noise: the offset sets how fast rays become opaque.
field::VMGrid grid_with(float offset, uint64_t seed) {
  field::VMGrid g = field::VMGrid::create({9, 8, 7}, {4, 2, 2}, 0.3f, seed);
  auto v = g.params.to_host();
  for (auto& x : v) x += offset;
  g.params.upload(v);
  return g;
}

// Checks the early-terminated march against the plain march: prefix, positions and sigma, and the stop rule.
// Returns how many samples the plain march has and the early one keeps.
std::pair<int64_t, int64_t> check_against_plain(const field::VMGrid& grid, float thr, bool jitter) {
  Tensor o, d;
  make_rays(24, 3, o, d);
  const auto cfg = config(jitter);
  const render::Samples plain = render::march(o, d, cfg, nullptr);
  const Tensor plain_sigma = field::density_forward(grid, plain.positions, field::DensityActivation::Relu);
  render::DensityMarch dm;
  dm.grid = &grid;
  dm.act = field::DensityActivation::Relu;
  dm.ert_threshold = thr;
  const render::Samples ert = render::march(o, d, cfg, nullptr, &dm);
  REQUIRE(ert.sigma.defined());
  const auto pc = plain.ray_count.to_host_i32(), po = plain.ray_offset.to_host_i32();
  const auto ec = ert.ray_count.to_host_i32(), eo = ert.ray_offset.to_host_i32();
  const auto ps = plain_sigma.to_host(), es = ert.sigma.to_host();
  const auto pp = plain.positions.to_host(), ep = ert.positions.to_host();
  const auto pt = plain.t.to_host(), et = ert.t.to_host();
  const auto eri = ert.ray_index.to_host_i32();
  const double tau_stop = -std::log(double(thr));
  for (size_t r = 0; r < pc.size(); ++r) {
    // The reference stop: the first sample after which the optical depth exceeds -log(thr).
    int want = pc[r];
    double tau = 0;
    for (int i = 0; i < pc[r]; ++i) {
      const double s = ps[size_t(po[r] + i)];
      if (s > 0) tau += s * double(cfg.step) * cfg.delta_scale;  // unit directions: |d| = 1
      if (tau > tau_stop) {
        want = i + 1;
        // A float sum may cross a hair later or earlier than the double one right at the threshold.
        if (std::abs(tau - tau_stop) < 1e-4 * tau_stop) want = -1;
        break;
      }
    }
    if (want >= 0) CHECK_MESSAGE(ec[r] == want, "ray " << r);
    for (int i = 0; i < std::min(ec[r], pc[r]); ++i) {
      const size_t a = size_t(po[r] + i), b = size_t(eo[r] + i);
      CHECK(et[b] == pt[a]);
      CHECK(eri[b] == int(r));
      for (int k = 0; k < 3; ++k) CHECK(ep[3 * b + k] == pp[3 * a + k]);
      CHECK(es[b] == doctest::Approx(ps[a]).epsilon(1e-6));
    }
  }
  return {plain.count, ert.count};
}

}  // namespace

TEST_CASE("early termination: each ray keeps the plain march's prefix up to the reference stop, sigma as density_forward") {
  for (bool jitter : {false, true}) {
    // Dense enough that most rays stop inside the box, at thresholds 1e-4 (the default) and 1e-2.
    for (float thr : {1e-4f, 1e-2f}) {
      const auto [plain, kept] = check_against_plain(grid_with(2.0f, 5), thr, jitter);
      CHECK(kept < plain / 2);
    }
  }
}

TEST_CASE("early termination hard cases: huge and zero densities, NaN grid values, rays missing the box") {
  SUBCASE("huge density: one sample a ray (the first one takes T to 0)") {
    field::VMGrid g = grid_with(0.0f, 6);
    g.params.fill(1e15f);  // sigma ~ 1e30 * 3 modes: finite, tau = inf after one sample
    Tensor o, d;
    make_rays(12, 4, o, d);
    render::DensityMarch dm{&g, field::DensityActivation::Relu, 1e-4f};
    const auto s = render::march(o, d, config(false), nullptr, &dm);
    const auto c = s.ray_count.to_host_i32();
    for (size_t r = 0; r + 1 < c.size(); ++r) CHECK(c[r] == 1);
    CHECK(c.back() == 0);  // the ray that misses the box
    for (float v : s.sigma.to_host()) CHECK(std::isfinite(v));
  }
  SUBCASE("zero density: no ray stops, the march equals the plain one") {
    field::VMGrid g = grid_with(0.0f, 6);
    g.params.fill(0.0f);
    const auto [plain, kept] = check_against_plain(g, 1e-4f, true);
    CHECK(kept == plain);
  }
  SUBCASE("NaN grid values add no optical depth (as the compositing treats them)") {
    field::VMGrid g = grid_with(0.0f, 6);
    g.params.fill(std::numeric_limits<float>::quiet_NaN());
    Tensor o, d;
    make_rays(6, 4, o, d);
    render::DensityMarch dm{&g, field::DensityActivation::Relu, 1e-4f};
    const auto plain = render::march(o, d, config(false), nullptr);
    const auto s = render::march(o, d, config(false), nullptr, &dm);
    CHECK(s.count == plain.count);
  }
  SUBCASE("thresholds outside (0, 1) and a missing grid are refused") {
    field::VMGrid g = grid_with(0.0f, 6);
    Tensor o, d;
    make_rays(2, 4, o, d);
    render::DensityMarch dm{&g, field::DensityActivation::Relu, 0.0f};
    CHECK_THROWS_AS(render::march(o, d, config(false), nullptr, &dm), host::Error);
    dm.ert_threshold = 1.0f;
    CHECK_THROWS_AS(render::march(o, d, config(false), nullptr, &dm), host::Error);
    dm.ert_threshold = 1e-4f;
    dm.grid = nullptr;
    CHECK_THROWS_AS(render::march(o, d, config(false), nullptr, &dm), host::Error);
  }
}

namespace {

// The deferred ops in double: y = a * c, n = F / (max(a, 0) + eps).
std::vector<double> ref_normalise(const std::vector<double>& F, const std::vector<double>& a, int C, double eps) {
  std::vector<double> n(F.size());
  for (size_t r = 0; r < a.size(); ++r)
    for (int c = 0; c < C; ++c) n[r * C + c] = F[r * C + c] / (std::max(a[r], 0.0) + eps);
  return n;
}
std::vector<double> ref_scale(const std::vector<double>& x, const std::vector<double>& a, int C) {
  std::vector<double> y(x.size());
  for (size_t r = 0; r < a.size(); ++r)
    for (int c = 0; c < C; ++c) y[r * C + c] = a[r] * x[r * C + c];
  return y;
}
double dot(const std::vector<double>& a, const std::vector<double>& b) {
  double s = 0;
  for (size_t i = 0; i < a.size(); ++i) s += a[i] * b[i];
  return s;
}

}  // namespace

TEST_CASE("deferred shading ops: forward vs double reference, backward vs central differences") {
  const int R = 37, C = 7;
  const float eps = render::kDeferredEps;
  auto Fv = testing::random_normal(size_t(R) * C, 1);
  auto av = testing::random_normal(R, 2, 0.3f, 0.5f);
  av[0] = 0.0f;     // empty ray
  av[1] = -0.2f;    // a negative opacity (not produced by compositing): clamped to 0 in the normaliser
  av[2] = 1.0f;
  const auto F = testing::to_double(Fv), a = testing::to_double(av);
  const auto G = testing::to_double(testing::random_normal(size_t(R) * C, 3));
  const Tensor tF = Tensor::from_host(Fv, {R, C}), ta = Tensor::from_host(av, {R});
  const Tensor tG = Tensor::from_host(std::vector<float>(G.begin(), G.end()), {R, C});

  testing::check_close(render::opacity_normalise_forward(tF, ta).to_host(), ref_normalise(F, a, C, eps), 1e-6, 0,
                       "normalise forward");
  testing::check_close(render::opacity_scale_forward(tF, ta).to_host(), ref_scale(F, a, C), 1e-6, 0, "scale forward");

  // Backward vs central differences of the double reference of L = G . op(F, a).
  Tensor da_n = Tensor::zeros({R}), da_s = Tensor::zeros({R});
  const auto dF_n = render::opacity_normalise_backward(tF, ta, tG, da_n).to_host();
  const auto dF_s = render::opacity_scale_backward(tF, ta, tG, da_s).to_host();
  const auto dan = da_n.to_host(), das = da_s.to_host();
  const double h = 1e-6;
  std::vector<float> got_F_n, got_F_s, got_a_n, got_a_s;
  std::vector<double> want_F_n, want_F_s, want_a_n, want_a_s;
  for (int r = 0; r < R; ++r) {
    if (r == 1) continue;  // negative a: the clamp's kink (checked below)
    for (int c = 0; c < C; c += 3) {
      auto Fp = F, Fm = F;
      Fp[size_t(r) * C + c] += h;
      Fm[size_t(r) * C + c] -= h;
      want_F_n.push_back((dot(G, ref_normalise(Fp, a, C, eps)) - dot(G, ref_normalise(Fm, a, C, eps))) / (2 * h));
      want_F_s.push_back((dot(G, ref_scale(Fp, a, C)) - dot(G, ref_scale(Fm, a, C))) / (2 * h));
      got_F_n.push_back(dF_n[size_t(r) * C + c]);
      got_F_s.push_back(dF_s[size_t(r) * C + c]);
    }
    // A small step: at a = 0 the normaliser's curvature scale is eps = 1e-4.
    const double ha = 1e-9;
    auto ap = a, am = a;
    ap[size_t(r)] += ha;
    am[size_t(r)] -= ha;
    if (r == 0) am[0] = 0;  // one-sided at the clamp: a >= 0 is the differentiable side
    const double span = ap[size_t(r)] - am[size_t(r)];
    // Only row r depends on a[r]: difference its terms alone (the empty ray's n ~ F / eps would otherwise
    // swamp the quotient in rounding).
    auto row_loss = [&](const std::vector<double>& y) {
      double l = 0;
      for (int c = 0; c < C; ++c) l += G[size_t(r) * C + c] * y[size_t(r) * C + c];
      return l;
    };
    want_a_n.push_back((row_loss(ref_normalise(F, ap, C, eps)) - row_loss(ref_normalise(F, am, C, eps))) / span);
    want_a_s.push_back((row_loss(ref_scale(F, ap, C)) - row_loss(ref_scale(F, am, C))) / span);
    got_a_n.push_back(dan[size_t(r)]);
    got_a_s.push_back(das[size_t(r)]);
  }
  testing::check_close(got_F_n, want_F_n, 1e-4, 1e-4, "normalise dF");
  testing::check_close(got_F_s, want_F_s, 1e-4, 1e-4, "scale dF");
  // a = 0 makes dn/da = -F/eps^2: large; relative tolerance covers it.
  testing::check_close(got_a_n, want_a_n, 1e-3, 1e-3, "normalise da");
  testing::check_close(got_a_s, want_a_s, 1e-4, 1e-4, "scale da");
  // The negative opacity gets no gradient from the normaliser (its forward is flat there).
  CHECK(dan[1] == 0.0f);

  SUBCASE("huge features stay finite through both ops and their backward") {
    std::vector<float> big(size_t(C), 0.0f);
    for (int c = 0; c < C; ++c) big[size_t(c)] = 1e30f * (c % 2 ? 1.0f : -1.0f);
    const Tensor bF = Tensor::from_host(big, {1, C}), ba = Tensor::from_host({0.5f}, {1});
    const Tensor bG = Tensor::from_host(std::vector<float>(size_t(C), 1e-3f), {1, C});
    Tensor dn = Tensor::zeros({1}), ds = Tensor::zeros({1});
    for (float v : render::opacity_normalise_forward(bF, ba).to_host()) CHECK(std::isfinite(v));
    for (float v : render::opacity_scale_forward(bF, ba).to_host()) CHECK(std::isfinite(v));
    for (float v : render::opacity_normalise_backward(bF, ba, bG, dn).to_host()) CHECK(std::isfinite(v));
    for (float v : render::opacity_scale_backward(bF, ba, bG, ds).to_host()) CHECK(std::isfinite(v));
    CHECK(std::isfinite(dn.to_host()[0]));
    CHECK(std::isfinite(ds.to_host()[0]));
  }
}

TEST_CASE("deferred shading ops: the opacity gradient accumulates, shapes are checked, no rays is fine") {
  const Tensor F = Tensor::from_host({1.0f, 2.0f}, {1, 2}), a = Tensor::from_host({0.5f}, {1});
  Tensor da = Tensor::from_host({10.0f}, {1});
  render::opacity_scale_backward(F, a, Tensor::from_host({1.0f, 1.0f}, {1, 2}), da);
  CHECK(da.to_host()[0] == doctest::Approx(13.0f));  // 10 + 1*1 + 1*2
  CHECK_THROWS_AS(render::opacity_scale_forward(F, Tensor::from_host({0.5f, 0.5f}, {2})), host::Error);
  CHECK_THROWS_AS(render::opacity_normalise_forward(Tensor::from_host({1.0f}, {1}), a), host::Error);
  const Tensor none = Tensor::zeros({0, 4}), none_a = Tensor::zeros({0});
  CHECK(render::opacity_normalise_forward(none, none_a).numel() == 0);
}
