// VM grid (kernels/grid.cl via lib/field/vm_grid.hpp, lib/field/alpha_mask.hpp): forward against a
// double-precision CPU reference, backward against central finite differences of that reference, the
// hard cases (exact corners and edges, points outside the box or NaN, empty point lists), regularisers,
// resampling and the alpha mask.
#include <doctest/doctest.h>

#include <array>
#include <cmath>
#include <limits>
#include <vector>

#include "host/tensor.hpp"
#include "lib/field/alpha_mask.hpp"
#include "lib/field/vm_grid.hpp"
#include "tests/grid_reference.hpp"
#include "tests/testing.hpp"

using namespace stylerf;
using field::DensityActivation;
using field::ScatterMode;
using field::VMGrid;
using host::Tensor;
using testing::check_close;

using testing::GridRef;
using testing::grid_test_points;

namespace {
GridRef ref_of(const VMGrid& g) { return GridRef{g.res, g.rank}; }
}  // namespace

TEST_CASE("VM density forward matches the double reference at random, corner, edge and outside points") {
  // Ranks 8/4/5 exercise the float4 path and the scalar tail; an uneven grid catches axis mix-ups.
  VMGrid g = VMGrid::create({5, 6, 7}, {8, 4, 5}, 0.5f, 11);
  GridRef ref = ref_of(g);
  const auto params = testing::to_double(g.params.to_host());
  const auto pts = grid_test_points(300, 3, true);
  const int n = int(pts.size() / 3);
  Tensor tp = Tensor::from_host(pts, {n, 3});
  for (auto act : {DensityActivation::Relu, DensityActivation::Softplus}) {
    CAPTURE(int(act));
    // Softplus(x - 10) of small x is ~e^-10: scale the grid up so the values are not all tiny.
    std::vector<double> want(n);
    for (int i = 0; i < n; ++i) {
      const double p[3] = {pts[3 * i], pts[3 * i + 1], pts[3 * i + 2]};
      want[i] = ref.density(params, p, act);
    }
    // Tolerance: float accumulation of <= 17 * 6 terms of size ~1: rtol 1e-5, atol 1e-5.
    check_close(field::density_forward(g, tp, act).to_host(), want, 1e-5, 1e-5, "density");
  }
  // The outside points and the NaN point give exactly 0.
  const auto got = field::density_forward(g, tp, DensityActivation::Relu).to_host();
  for (int i = n - 5; i < n; ++i) CHECK(got[i] == 0.0f);
}

TEST_CASE("VM density at exact grid nodes equals the node values (align_corners semantics)") {
  // A rank-1 grid with planes = 1 and line 0 = node index: density at z-node k is exactly k (other lines 0).
  const std::array<int, 3> res{3, 4, 5}, rank{1, 1, 1};
  GridRef ref{res, rank};
  std::vector<float> p(ref.numel(), 0.0f);
  for (size_t k = 0; k < ref.line_off(0); ++k) p[k] = 1.0f;
  for (int z = 0; z < res[2]; ++z) p[ref.line_off(0) + z] = float(z);
  VMGrid g = VMGrid::from_params(res, rank, Tensor::from_host(p, {int64_t(p.size())}));
  std::vector<float> pts;
  for (int z = 0; z < res[2]; ++z) {
    const float q = -1.0f + 2.0f * z / (res[2] - 1);
    pts.insert(pts.end(), {0.3f, -0.7f, q});
  }
  const auto got = field::density_forward(g, Tensor::from_host(pts, {res[2], 3}), DensityActivation::Relu).to_host();
  for (int z = 0; z < res[2]; ++z) CHECK(got[z] == doctest::Approx(z).epsilon(1e-6));
}

TEST_CASE("VM features forward matches the double reference") {
  VMGrid g = VMGrid::create({4, 7, 5}, {12, 3, 6}, 0.5f, 12);
  GridRef ref = ref_of(g);
  const auto params = testing::to_double(g.params.to_host());
  const auto pts = grid_test_points(200, 4, true);
  const int n = int(pts.size() / 3);
  std::vector<double> want;
  for (int i = 0; i < n; ++i) {
    const double p[3] = {pts[3 * i], pts[3 * i + 1], pts[3 * i + 2]};
    auto f = ref.features(params, p);
    want.insert(want.end(), f.begin(), f.end());
  }
  // Each feature is one product of two interpolations: rtol 1e-5, atol 1e-6.
  check_close(field::features_forward(g, Tensor::from_host(pts, {n, 3})).to_host(), want, 1e-5, 1e-6, "features");
}

TEST_CASE("VM density backward matches finite differences of the reference (5^3, rank 2), every scatter mode") {
  // Softplus shifted by -10 is smooth everywhere; relu too away from 0 (the grid is offset so f > 0).
  const auto pts = grid_test_points(40, 5, true);
  const int n = int(pts.size() / 3);
  const auto gs = testing::to_double(testing::random_normal(n, 6));
  Tensor tp = Tensor::from_host(pts, {n, 3});
  for (auto act : {DensityActivation::Softplus, DensityActivation::Relu}) {
    // Softplus(f - 10) needs f of order 10 to have gradients worth checking: a larger init there.
    VMGrid g = VMGrid::create({5, 5, 5}, {2, 2, 2}, act == DensityActivation::Softplus ? 2.5f : 0.6f, 21);
    GridRef ref = ref_of(g);
    auto params = testing::to_double(g.params.to_host());
    auto loss = [&](const std::vector<double>& x) {
      double s = 0;
      for (int i = 0; i < n; ++i) {
        const double p[3] = {pts[3 * i], pts[3 * i + 1], pts[3 * i + 2]};
        s += gs[i] * ref.density(x, p, act);
      }
      return s;
    };
    const auto fd = testing::finite_difference(loss, params, 1e-5);
    Tensor sigma = field::density_forward(g, tp, act);
    Tensor dsig = Tensor::from_host(std::vector<float>(gs.begin(), gs.end()), {n});
    for (auto mode : {ScatterMode::Private, ScatterMode::Fixed}) {
      CAPTURE(int(act));
      CAPTURE(int(mode));
      Tensor dgrid = Tensor::zeros(g.params.shape());
      field::density_backward(g, tp, sigma, dsig, dgrid, act, mode);
      // FD truncation ~h^2 plus float rounding in sigma: rtol 1e-3, atol 1e-4 (relu kinks are avoided:
      // a point with |f| < 1e-3 would flip; none is that close for this seed, else this fails loudly).
      check_close(dgrid.to_host(), fd, 1e-3, 1e-4, "density grad");
      double mx = 0;
      for (double v : fd) mx = std::max(mx, std::fabs(v));
      CHECK(mx > 0.1);  // gradients large against atol: the comparison can fail
    }
  }
}

TEST_CASE("VM features backward matches finite differences, and every scatter mode agrees") {
  VMGrid g = VMGrid::create({5, 5, 5}, {2, 2, 2}, 0.6f, 22);
  GridRef ref = ref_of(g);
  auto params = testing::to_double(g.params.to_host());
  const auto pts = grid_test_points(30, 7, true);
  const int n = int(pts.size() / 3), F = g.features();
  const auto gf = testing::to_double(testing::random_normal(size_t(n) * F, 8));
  auto loss = [&](const std::vector<double>& x) {
    double s = 0;
    for (int i = 0; i < n; ++i) {
      const double p[3] = {pts[3 * i], pts[3 * i + 1], pts[3 * i + 2]};
      auto f = ref.features(x, p);
      for (int k = 0; k < F; ++k) s += gf[size_t(i) * F + k] * f[k];
    }
    return s;
  };
  const auto fd = testing::finite_difference(loss, params, 1e-5);
  // The analytic reference gradient used by the larger test below agrees with FD (validates it).
  check_close(std::vector<float>(fd.begin(), fd.end()), ref.features_grad(params, std::vector<double>(pts.begin(), pts.end()), gf),
              1e-6, 1e-6, "reference analytic vs FD");
  Tensor tp = Tensor::from_host(pts, {n, 3});
  Tensor tg = Tensor::from_host(std::vector<float>(gf.begin(), gf.end()), {n, F});
  for (auto mode : {ScatterMode::Private, ScatterMode::Fixed}) {
    Tensor dgrid = Tensor::zeros(g.params.shape());
    field::features_backward(g, tp, tg, dgrid, mode);
    check_close(dgrid.to_host(), fd, 1e-4, 1e-5, "features grad");
  }
}

TEST_CASE("VM scatter with many points (several gradient copies) matches the reference and accumulates") {
  VMGrid g = VMGrid::create({9, 8, 7}, {4, 4, 8}, 0.3f, 23);
  GridRef ref = ref_of(g);
  auto params = testing::to_double(g.params.to_host());
  // Clustered points so many hit the same cells (contention for the per-point fixed-point path).
  auto pts = testing::random_uniform(size_t(3) * 20000, 9, -0.3f, 0.2f);
  const int n = int(pts.size() / 3), F = g.features();
  const auto gf = testing::random_normal(size_t(n) * F, 10);
  const auto want1 = ref.features_grad(params, testing::to_double(pts), testing::to_double(gf));
  std::vector<double> want(want1.size());
  for (size_t k = 0; k < want.size(); ++k) want[k] = 1.0 + want1[k];  // accumulates into an existing gradient
  Tensor tp = Tensor::from_host(pts, {n, 3}), tg = Tensor::from_host(gf, {n, F});
  std::vector<float> first;
  for (auto mode : {ScatterMode::Private, ScatterMode::Fixed, ScatterMode::Private}) {
    Tensor dgrid = Tensor::full(g.params.shape(), 1.0f);
    field::features_backward(g, tp, tg, dgrid, mode);
    const auto got = dgrid.to_host();
    // Sums of up to ~20000 float terms of size ~0.1: rtol 1e-3, atol 1e-3.
    check_close(got, want, 1e-3, 1e-3, "many-point grad");
    if (mode == ScatterMode::Private) {
      if (first.empty())
        first = got;
      else
        CHECK(got == first);  // the privatised scatter is deterministic: bit-identical on a rerun
    }
  }
}

TEST_CASE("VM backward with ranks that use every vector width (8, 4 and scalar tails) matches the reference") {
  // Ranks 13 = 8+4+1, 8, 7 = 4+3 and 24 = 3x8, 12 = 8+4, 4 cover the kernels' float8 / float4 / scalar rank
  // chunks (the earlier FD tests use rank 2, scalar only). Points cluster so neighbouring points share
  // taps (the read-modify-write order the privatised scatter relies on), plus the special points.
  for (auto rank : {std::array<int, 3>{13, 8, 7}, std::array<int, 3>{24, 12, 4}}) {
    CAPTURE(rank[0]);
    VMGrid g = VMGrid::create({6, 5, 7}, rank, 0.4f, 41);
    GridRef ref = ref_of(g);
    const auto params = testing::to_double(g.params.to_host());
    auto pts = testing::random_uniform(size_t(3) * 3000, 42, -0.6f, 0.4f);
    const auto special = grid_test_points(0, 43, true);
    pts.insert(pts.end(), special.begin(), special.end());
    const int n = int(pts.size() / 3), F = g.features();
    Tensor tp = Tensor::from_host(pts, {n, 3});
    // Features: random upstream gradient, some rows and some 8-chunks exactly zero (skipped chunks).
    auto gf = testing::random_normal(size_t(n) * F, 44);
    for (int i = 0; i < n; i += 7)
      for (int k = 0; k < F; ++k) gf[size_t(i) * F + k] = 0.0f;
    for (int i = 3; i < n; i += 5)
      for (int k = 0; k < 8; ++k) gf[size_t(i) * F + k] = 0.0f;
    const auto want_f = ref.features_grad(params, testing::to_double(pts), testing::to_double(gf));
    // Density (relu): d sigma/d f = [sigma > 0] for every rank, i.e. a features gradient replicated over
    // ranks; taken from the kernel's own sigma so points at the kink cannot disagree.
    const auto dsig = testing::random_normal(size_t(n), 45);
    Tensor sp = field::density_forward(g, tp, DensityActivation::Relu);
    const auto sig = sp.to_host();
    std::vector<double> gd(size_t(n) * F);
    int active = 0;
    for (int i = 0; i < n; ++i) {
      active += sig[i] > 0.0f;
      for (int k = 0; k < F; ++k) gd[size_t(i) * F + k] = sig[i] > 0.0f ? double(dsig[i]) : 0.0;
    }
    CHECK(active > n / 10);  // both branches of relu occur
    CHECK(active < n);
    const auto want_d = ref.features_grad(params, testing::to_double(pts), gd);
    for (auto mode : {ScatterMode::Private, ScatterMode::Fixed}) {
      CAPTURE(int(mode));
      Tensor dgf = Tensor::zeros(g.params.shape());
      field::features_backward(g, tp, Tensor::from_host(gf, {n, F}), dgf, mode);
      // Sums of ~3000 float terms of size ~1: rtol 1e-4, atol 1e-4.
      check_close(dgf.to_host(), want_f, 1e-4, 1e-4, "features grad (wide ranks)");
      Tensor dgd = Tensor::zeros(g.params.shape());
      field::density_backward(g, tp, sp, Tensor::from_host(dsig, {n}), dgd, DensityActivation::Relu, mode);
      check_close(dgd.to_host(), want_d, 1e-4, 1e-4, "density grad (wide ranks)");
      double mx = 0;
      for (double v : want_d) mx = std::max(mx, std::fabs(v));
      CHECK(mx > 1.0);  // gradients large against atol: the comparison can fail
    }
  }
}

TEST_CASE("VM empty point lists and all-outside points: no launch errors, zero gradient") {
  VMGrid g = VMGrid::create({4, 4, 4}, {2, 2, 2}, 0.5f, 31);
  Tensor empty({0, 3});
  CHECK(field::density_forward(g, empty, DensityActivation::Relu).numel() == 0);
  CHECK(field::features_forward(g, empty).numel() == 0);
  Tensor dgrid = Tensor::zeros(g.params.shape());
  field::density_backward(g, empty, Tensor({0}), Tensor({0}), dgrid, DensityActivation::Relu);
  field::features_backward(g, empty, Tensor({0, 6}), dgrid);
  std::vector<float> out = {2, 0, 0, 0, -1.01f, 0, 0, 0, 5};
  Tensor tp = Tensor::from_host(out, {3, 3});
  Tensor sigma = field::density_forward(g, tp, DensityActivation::Softplus);
  for (float s : sigma.to_host()) CHECK(s == 0.0f);
  field::density_backward(g, tp, sigma, Tensor::full({3}, 1.0f), dgrid, DensityActivation::Softplus);
  field::features_backward(g, tp, Tensor::full({3, 6}, 1.0f), dgrid);
  for (float d : dgrid.to_host()) CHECK(d == 0.0f);
}

TEST_CASE("TV and L1 regularisers: forward vs reference, backward vs finite differences") {
  VMGrid g = VMGrid::create({4, 5, 3}, {2, 3, 1}, 0.5f, 41);
  GridRef ref = ref_of(g);
  auto params = testing::to_double(g.params.to_host());
  // Forward: float partial sums, host sum in double: rtol 1e-5.
  CHECK(field::tv_forward(g) == doctest::Approx(ref.tv(params)).epsilon(1e-5));
  CHECK(field::l1_forward(g) == doctest::Approx(ref.l1(params)).epsilon(1e-5));
  const float wtv = 0.7f, wl1 = 1.3f;
  const auto fd_tv = testing::finite_difference([&](const std::vector<double>& x) { return wtv * ref.tv(x); }, params);
  const auto fd_l1 = testing::finite_difference([&](const std::vector<double>& x) { return wl1 * ref.l1(x); }, params);
  Tensor dgrid = Tensor::zeros(g.params.shape());
  field::tv_backward(g, wtv, dgrid);
  check_close(dgrid.to_host(), fd_tv, 1e-4, 1e-6, "TV grad");
  dgrid.zero();
  field::l1_backward(g, wl1, dgrid);
  check_close(dgrid.to_host(), fd_l1, 1e-4, 1e-6, "L1 grad");  // no parameter is within h of 0
  // A plane row longer than one work-group (70 x rank 2 = 140 elements along u, groups of 64).
  {
    VMGrid w = VMGrid::create({70, 9, 5}, {1, 2, 1}, 0.5f, 42);
    GridRef wref = ref_of(w);
    const auto wp = testing::to_double(w.params.to_host());
    const auto fd = testing::finite_difference([&](const std::vector<double>& x) { return wtv * wref.tv(x); }, wp);
    Tensor dw = Tensor::zeros(w.params.shape());
    field::tv_backward(w, wtv, dw);
    check_close(dw.to_host(), fd, 1e-4, 1e-6, "TV grad, rows over several work-groups");
  }
  // Constant planes: TV 0 with zero gradient (no NaN).
  VMGrid c = VMGrid::from_params(g.res, g.rank, Tensor::full(g.params.shape(), 0.25f));
  CHECK(field::tv_forward(c) == 0.0);
  dgrid.zero();
  field::tv_backward(c, 1.0f, dgrid);
  for (float d : dgrid.to_host()) CHECK(d == 0.0f);
}

TEST_CASE("VM resampling: upsampling and sub-box crop match the reference; linear fields are kept exactly") {
  VMGrid g = VMGrid::create({5, 4, 6}, {2, 3, 4}, 0.5f, 51);
  GridRef ref = ref_of(g);
  auto params = testing::to_double(g.params.to_host());
  const std::array<float, 3> lo{-0.5f, -1.0f, 0.0f}, hi{0.75f, 1.0f, 1.0f};
  for (bool crop : {false, true}) {
    const std::array<int, 3> nr{9, 7, 11};
    VMGrid u = crop ? field::resample(g, nr, lo, hi) : field::resample(g, nr);
    // The new grid sampled at its nodes equals the old one sampled at the mapped positions: compare the
    // density (sum of products) at every node of the new grid.
    std::vector<float> pts;
    std::vector<double> want;
    for (int z = 0; z < nr[2]; ++z)
      for (int y = 0; y < nr[1]; ++y)
        for (int x = 0; x < nr[0]; ++x) {
          const int idx[3] = {x, y, z};
          double q[3], old[3];
          for (int a = 0; a < 3; ++a) {
            q[a] = -1.0 + 2.0 * idx[a] / (nr[a] - 1);
            const double l = crop ? lo[a] : -1.0, h = crop ? hi[a] : 1.0;
            old[a] = l + (h - l) * (q[a] + 1) / 2;
          }
          pts.insert(pts.end(), {float(q[0]), float(q[1]), float(q[2])});
          want.push_back(ref.raw_density(params, old));
        }
    const int n = int(pts.size() / 3);
    // relu would hide negative values: compare raw features summed per point instead.
    const auto feat = field::features_forward(u, Tensor::from_host(pts, {n, 3})).to_host();
    std::vector<float> got(n, 0.0f);
    for (int i = 0; i < n; ++i)
      for (int k = 0; k < u.features(); ++k) got[i] += feat[size_t(i) * u.features() + k];
    check_close(got, want, 1e-4, 1e-5, crop ? "cropped grid" : "upsampled grid");
  }
}

TEST_CASE("alpha mask matches the reference occupancy (threshold + 3x3x3 dilation) and its tight box") {
  // A grid whose density is a blob: relu(plane values * line values) with a random grid, threshold high
  // enough that part of the box is empty.
  VMGrid g = VMGrid::create({8, 8, 8}, {2, 2, 2}, 0.7f, 61);
  GridRef ref = ref_of(g);
  auto params = testing::to_double(g.params.to_host());
  const std::array<int, 3> mr{6, 5, 7};
  const float step = 0.1f, thr = 0.05f;
  field::AlphaMask m = field::build_alpha_mask(g, DensityActivation::Relu, mr, step, thr);
  std::vector<uint8_t> raw(size_t(mr[0]) * mr[1] * mr[2]), want(raw.size());
  int near_threshold = 0;
  for (int z = 0; z < mr[2]; ++z)
    for (int y = 0; y < mr[1]; ++y)
      for (int x = 0; x < mr[0]; ++x) {
        const double p[3] = {-1 + (2.0 * x + 1) / mr[0], -1 + (2.0 * y + 1) / mr[1], -1 + (2.0 * z + 1) / mr[2]};
        const double alpha = 1 - std::exp(-ref.density(params, p, DensityActivation::Relu) * step);
        near_threshold += std::fabs(alpha - thr) < 1e-5;
        raw[(size_t(z) * mr[1] + y) * mr[0] + x] = alpha > thr;
      }
  REQUIRE(near_threshold == 0);  // no voxel is ambiguous in float for this seed
  std::array<int, 3> blo{99, 99, 99}, bhi{-1, -1, -1};
  int64_t occ = 0;
  for (int z = 0; z < mr[2]; ++z)
    for (int y = 0; y < mr[1]; ++y)
      for (int x = 0; x < mr[0]; ++x) {
        uint8_t o = 0;
        for (int dz = -1; dz <= 1; ++dz)
          for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) {
              const int xx = x + dx, yy = y + dy, zz = z + dz;
              if (xx >= 0 && yy >= 0 && zz >= 0 && xx < mr[0] && yy < mr[1] && zz < mr[2])
                o |= raw[(size_t(zz) * mr[1] + yy) * mr[0] + xx];
            }
        want[(size_t(z) * mr[1] + y) * mr[0] + x] = o;
        if (o) {
          ++occ;
          const int c[3] = {x, y, z};
          for (int a = 0; a < 3; ++a) blo[a] = std::min(blo[a], c[a]), bhi[a] = std::max(bhi[a], c[a]);
        }
      }
  CHECK(m.to_host() == want);
  CHECK(m.occupied == occ);
  REQUIRE(occ > 0);
  CHECK(occ < int64_t(want.size()));  // the test means something: part of the box is empty
  for (int a = 0; a < 3; ++a) {
    CHECK(m.lo[a] == doctest::Approx(-1.0 + 2.0 * blo[a] / mr[a]));
    CHECK(m.hi[a] == doctest::Approx(-1.0 + 2.0 * (bhi[a] + 1) / mr[a]));
  }
  // A zero grid: nothing occupied, box empty (lo > hi).
  VMGrid z = VMGrid::from_params(g.res, g.rank, Tensor::zeros(g.params.shape()));
  field::AlphaMask e = field::build_alpha_mask(z, DensityActivation::Relu, mr, step, thr);
  CHECK(e.empty());
  CHECK(e.lo[0] > e.hi[0]);
}
