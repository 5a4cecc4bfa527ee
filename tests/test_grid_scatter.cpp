// The VM grids' deterministic fixed-point scatter (kernels/grid_fixed.cl, ScatterMode::Fixed) on its hard
// cases: bit-identical results from run to run and for any order of the points, every sample on one
// texel, samples on the grid's faces, edges and corners, empty and all-zero inputs, gradients near the
// float range's ends, and non-finite input (NaN out, never a silent finite value). Its agreement with
// finite differences and the other scatters is in test_grid.cpp.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include "host/error.hpp"
#include "host/tensor.hpp"
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

namespace {

std::vector<float> features_grad(const VMGrid& g, const std::vector<float>& pts, const std::vector<float>& gf,
                                 ScatterMode mode, float init = 0.0f) {
  const int n = int(pts.size() / 3), F = g.features();
  Tensor dgrid = Tensor::full(g.params.shape(), init);
  field::features_backward(g, Tensor::from_host(pts, {n, 3}), Tensor::from_host(gf, {n, F}), dgrid, mode);
  return dgrid.to_host();
}

std::vector<double> reference(const VMGrid& g, const std::vector<float>& pts, const std::vector<float>& gf) {
  GridRef ref{g.res, g.rank};
  return ref.features_grad(testing::to_double(g.params.to_host()), testing::to_double(pts), testing::to_double(gf));
}

double max_abs_error(const std::vector<float>& got, const std::vector<double>& want) {
  double e = 0;
  for (size_t k = 0; k < got.size(); ++k) e = testing::max_or_nan(e, std::fabs(double(got[k]) - want[k]));
  return e;
}

}  // namespace

TEST_CASE("fixed-point scatter: bit-identical on a rerun and for any order of the points") {
  VMGrid g = VMGrid::create({9, 8, 7}, {4, 4, 8}, 0.3f, 61);
  // Clustered points, so many share texels: the case where a float atomic sum depends on arrival order.
  const auto pts = testing::random_uniform(size_t(3) * (testing::small_run() ? 2000 : 20000), 62, -0.3f, 0.2f);
  const int n = int(pts.size() / 3), F = g.features();
  const auto gf = testing::random_normal(size_t(n) * F, 63);
  const auto first = features_grad(g, pts, gf, ScatterMode::Fixed);
  CHECK(features_grad(g, pts, gf, ScatterMode::Fixed) == first);
  // The same points in another order (rows of gf permuted with them): the same bits.
  std::vector<int> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::shuffle(order.begin(), order.end(), std::mt19937(64));
  std::vector<float> p2(pts.size()), g2(gf.size());
  for (int i = 0; i < n; ++i) {
    std::copy_n(&pts[size_t(order[i]) * 3], 3, &p2[size_t(i) * 3]);
    std::copy_n(&gf[size_t(order[i]) * F], F, &g2[size_t(i) * F]);
  }
  CHECK(features_grad(g, p2, g2, ScatterMode::Fixed) == first);
  // And it is at least as close to the double reference as the float scatters (one rounding per element).
  const auto want = reference(g, pts, gf);
  const double e_fixed = max_abs_error(first, want);
  const double e_private = max_abs_error(features_grad(g, pts, gf, ScatterMode::Private), want);
  MESSAGE("max |error| vs double: fixed " << e_fixed << ", private " << e_private);
  CHECK(e_fixed <= e_private);
  CHECK(e_fixed < 1e-4);
}

TEST_CASE("fixed-point scatter: every sample on one texel, and samples on faces, edges and corners") {
  VMGrid g = VMGrid::create({5, 6, 4}, {3, 2, 5}, 0.5f, 65);
  const int F = g.features();
  SUBCASE("20000 samples at one point inside a cell") {
    const int n = testing::small_run() ? 2000 : 20000;
    std::vector<float> pts;
    for (int i = 0; i < n; ++i) pts.insert(pts.end(), {0.13f, -0.41f, 0.27f});
    const auto gf = testing::random_normal(size_t(n) * F, 66);
    const auto got = features_grad(g, pts, gf, ScatterMode::Fixed);
    // The taps' weights are computed in float from float coordinates (relative error ~1e-6, the same for
    // every sample here); the sum itself adds nothing to that.
    check_close(got, reference(g, pts, gf), 1e-5, 1e-5, "one texel");
  }
  SUBCASE("grid nodes, faces, edges, corners, points outside and NaN") {
    auto pts = testing::grid_test_points(0, 67, true);
    // Exact grid nodes: every tap weight but one is zero.
    for (int z = 0; z < 4; ++z)
      for (int x = 0; x < 5; ++x) pts.insert(pts.end(), {-1.0f + 0.5f * x, 1.0f, -1.0f + 2.0f * z / 3.0f});
    const int n = int(pts.size() / 3);
    const auto gf = testing::random_normal(size_t(n) * F, 68);
    const auto got = features_grad(g, pts, gf, ScatterMode::Fixed);
    for (float v : got) REQUIRE(std::isfinite(v));
    check_close(got, reference(g, pts, gf), 1e-6, 1e-6, "faces and corners");
  }
}

TEST_CASE("fixed-point scatter: empty, all-zero and all-outside inputs leave the gradient as it was") {
  VMGrid g = VMGrid::create({4, 4, 4}, {2, 2, 2}, 0.5f, 69);
  const int F = g.features();
  CHECK(features_grad(g, {}, {}, ScatterMode::Fixed, 0.5f) == std::vector<float>(size_t(g.numel()), 0.5f));
  const auto pts = testing::random_uniform(size_t(3) * 100, 70, -1.0f, 1.0f);
  CHECK(features_grad(g, pts, std::vector<float>(size_t(100) * F, 0.0f), ScatterMode::Fixed, 0.5f) ==
        std::vector<float>(size_t(g.numel()), 0.5f));
  const std::vector<float> outside = {2, 0, 0, 0, -1.01f, 0, 0, 0, 5};
  CHECK(features_grad(g, outside, std::vector<float>(size_t(3) * F, 1.0f), ScatterMode::Fixed, 0.5f) ==
        std::vector<float>(size_t(g.numel()), 0.5f));
  // Density with a zero upstream gradient, then a real one (the accumulator was left zeroed).
  const int n = 100;
  Tensor tp = Tensor::from_host(pts, {n, 3});
  Tensor sigma = field::density_forward(g, tp, DensityActivation::Softplus);
  Tensor dgrid = Tensor::zeros(g.params.shape());
  field::density_backward(g, tp, sigma, Tensor::zeros({n}), dgrid, DensityActivation::Softplus, ScatterMode::Fixed);
  for (float v : dgrid.to_host()) REQUIRE(v == 0.0f);
}

TEST_CASE("fixed-point scatter: gradients near the ends of the float range keep their relative precision") {
  VMGrid g = VMGrid::create({6, 5, 7}, {4, 4, 4}, 0.4f, 71);
  const int n = testing::small_run() ? 500 : 3000, F = g.features();
  const auto pts = testing::random_uniform(size_t(3) * n, 72, -1.0f, 1.0f);
  const auto base = testing::random_normal(size_t(n) * F, 73);
  for (float scale : {1e-30f, 1e-3f, 1e25f}) {
    CAPTURE(scale);
    std::vector<float> gf(base);
    for (float& v : gf) v *= scale;
    const auto want = reference(g, pts, gf);
    double mx = 0;
    for (double v : want) mx = std::max(mx, std::fabs(v));
    const auto got = features_grad(g, pts, gf, ScatterMode::Fixed);
    for (float v : got) REQUIRE(std::isfinite(v));
    check_close(got, want, 1e-5, 1e-6 * mx, "scaled gradient");
  }
}

TEST_CASE("fixed-point scatter: a NaN or Inf gradient turns the gradient NaN, never a silent finite value") {
  VMGrid g = VMGrid::create({4, 5, 4}, {2, 3, 2}, 0.5f, 74);
  const auto pts = testing::random_uniform(size_t(3) * 50, 75, -0.9f, 0.9f);
  const int n = 50, F = g.features();
  for (float bad : {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity()}) {
    auto gf = testing::random_normal(size_t(n) * F, 76);
    gf[size_t(17) * F + 2] = bad;
    const auto got = features_grad(g, pts, gf, ScatterMode::Fixed);
    CHECK(std::any_of(got.begin(), got.end(), [](float v) { return std::isnan(v); }));
    // The next call with finite input is finite again (the flag and the accumulator were reset).
    gf[size_t(17) * F + 2] = 0.5f;
    for (float v : features_grad(g, pts, gf, ScatterMode::Fixed)) REQUIRE(std::isfinite(v));
  }
  // A NaN in the grid itself (a diverged model) is caught too.
  std::vector<float> params = g.params.to_host();
  params[3] = std::numeric_limits<float>::quiet_NaN();
  VMGrid bad = VMGrid::from_params(g.res, g.rank, Tensor::from_host(params, {g.numel()}));
  const auto got = features_grad(bad, pts, testing::random_normal(size_t(n) * F, 77), ScatterMode::Fixed);
  CHECK(std::any_of(got.begin(), got.end(), [](float v) { return std::isnan(v); }));
}

TEST_CASE("scatter modes parse by name, and Auto resolves to a mode this device can run") {
  CHECK(field::parse_scatter_mode("fixed") == ScatterMode::Fixed);
  CHECK(field::parse_scatter_mode("private") == ScatterMode::Private);
  CHECK_THROWS_WITH_AS(field::parse_scatter_mode("atomic"), doctest::Contains("auto, private, fixed"),
                       host::Error);
  const ScatterMode m = field::resolved_scatter_mode(ScatterMode::Auto);
  CHECK(m != ScatterMode::Auto);
  MESSAGE("Auto scatter on this device: " << std::string(field::scatter_mode_name(m)));
}
