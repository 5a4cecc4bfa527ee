// relu, 2x2 max pooling and x2 nearest upsampling: forward against double references, backward against
// central finite differences, ties, extreme magnitudes, and bad-shape errors.
//
// These ops only select, copy or add a few floats, so forward results must match the reference
// exactly (max/relu/copy) or to 1 ulp-ish (the 4-term sums of upsample backward: rtol 1e-6).
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "host/error.hpp"
#include "lib/nn/ops.hpp"
#include "tests/testing.hpp"

using namespace stylerf;
using testing::error_of;
using host::Shape;
using host::Tensor;
using testing::check_close;
using testing::to_double;

namespace {

// Distinct values 0.01 apart in random order, none within 0.005 of 0: the max / relu kinks are never
// within the finite-difference step (h = 1e-3), so the differences are exact.
std::vector<float> away_from_kinks(size_t n, uint64_t seed) {
  std::vector<size_t> perm(n);
  for (size_t i = 0; i < n; ++i) perm[i] = i;
  std::mt19937_64 rng(seed);
  std::shuffle(perm.begin(), perm.end(), rng);
  std::vector<float> v(n);
  for (size_t i = 0; i < n; ++i) v[i] = (float(perm[i]) - float(n / 2) + 0.5f) * 0.01f;
  return v;
}

std::vector<double> ref_relu(const std::vector<double>& x) {
  std::vector<double> y(x.size());
  for (size_t i = 0; i < x.size(); ++i) y[i] = x[i] > 0 ? x[i] : 0.0;
  return y;
}

std::vector<double> ref_pool(const std::vector<double>& x, int NC, int H, int W) {
  std::vector<double> y(size_t(NC) * (H / 2) * (W / 2));
  for (int p = 0; p < NC; ++p)
    for (int oy = 0; oy < H / 2; ++oy)
      for (int ox = 0; ox < W / 2; ++ox) {
        auto at = [&](int dy, int dx) { return x[(size_t(p) * H + 2 * oy + dy) * W + 2 * ox + dx]; };
        y[(size_t(p) * (H / 2) + oy) * (W / 2) + ox] = std::max(std::max(at(0, 0), at(0, 1)), std::max(at(1, 0), at(1, 1)));
      }
  return y;
}

std::vector<double> ref_upsample(const std::vector<double>& x, int NC, int H, int W) {
  std::vector<double> y(size_t(NC) * 4 * H * W);
  for (int p = 0; p < NC; ++p)
    for (int yy = 0; yy < 2 * H; ++yy)
      for (int xx = 0; xx < 2 * W; ++xx)
        y[(size_t(p) * 2 * H + yy) * 2 * W + xx] = x[(size_t(p) * H + yy / 2) * W + xx / 2];
  return y;
}


}  // namespace

TEST_CASE("relu forward and backward") {
  // 210 elements: 26 full float8 groups plus a tail of 2.
  const Shape s{2, 3, 5, 7};
  auto x = away_from_kinks(210, 1);
  auto g = testing::random_normal(210, 2);
  Tensor tx = Tensor::from_host(x, s);
  Tensor y = nn::relu_forward(tx);
  check_close(y.to_host(), ref_relu(to_double(x)), 0.0, 0.0, "relu_forward (exact)");
  Tensor dx = nn::relu_backward(y, Tensor::from_host(g, s));
  auto gd = to_double(g);
  auto f = [&](const std::vector<double>& v) { return testing::dot(gd, ref_relu(v)); };
  // Piecewise linear and no kink within h: differences exact to double rounding; rtol/atol 1e-6.
  check_close(dx.to_host(), testing::finite_difference(f, to_double(x), 1e-3), 1e-6, 1e-6, "relu_backward");
}

TEST_CASE("relu at zero passes no gradient; extreme magnitudes stay exact") {
  // 2e-38: just above float's smallest normal (1.18e-38); below it the kernels flush to zero by design
  // (-cl-denorms-are-zero, host/runtime.cpp).
  std::vector<float> x = {0.0f, -0.0f, 1e30f, -1e30f, 1e-30f, -1e-30f, 3.0e38f, -3.0e38f, 2e-38f, 0.0f, 5.0f};
  Tensor tx = Tensor::from_host(x, {1, 1, 1, 11});
  auto y = nn::relu_forward(tx).to_host();
  check_close(y, ref_relu(to_double(x)), 0.0, 0.0, "relu extreme (exact)");
  auto dx = nn::relu_backward(nn::relu_forward(tx), Tensor::full({1, 1, 1, 11}, 1e30f)).to_host();
  std::vector<double> want = {0, 0, 1e30, 0, 1e30, 0, 1e30, 0, 1e30, 0, 1e30};
  check_close(dx, want, 1e-7, 0.0, "relu_backward extreme");
}

TEST_CASE("maxpool2x2 forward and backward") {
  // W = 22: one 8-wide output group plus a tail of 3; W = 6: tail only. Odd sizes floor (the last row /
  // column is in no window and gets a zero gradient): W = 35 (vector path + tail + a dropped column),
  // H = 5 (a dropped row), 3 x 3 (one window), W = 2 with odd H.
  const int sizes[][2] = {{4, 22}, {4, 6}, {4, 35}, {5, 22}, {5, 7}, {3, 3}, {7, 2}};
  for (const auto& hw : sizes) {
    const int N = 2, C = 3, H = hw[0], W = hw[1];
    CAPTURE(H);
    CAPTURE(W);
    const size_t n = size_t(N) * C * H * W;
    auto x = away_from_kinks(n, 10 + W);
    auto g = testing::random_normal(size_t(N) * C * (H / 2) * (W / 2), 20 + W);
    Tensor tx = Tensor::from_host(x, {N, C, H, W});
    Tensor y = nn::maxpool2x2_forward(tx);
    CHECK(y.shape() == Shape{N, C, H / 2, W / 2});
    check_close(y.to_host(), ref_pool(to_double(x), N * C, H, W), 0.0, 0.0, "maxpool forward (exact)");
    Tensor dx = nn::maxpool2x2_backward(tx, Tensor::from_host(g, {N, C, H / 2, W / 2}));
    auto gd = to_double(g);
    auto f = [&](const std::vector<double>& v) { return testing::dot(gd, ref_pool(v, N * C, H, W)); };
    check_close(dx.to_host(), testing::finite_difference(f, to_double(x), 1e-3), 1e-6, 1e-6, "maxpool backward");
  }
}

TEST_CASE("maxpool2x2 ties: the gradient goes to exactly one element, the first maximum") {
  for (int W : {20, 6}) {  // vector path (+ tail) and tail only
    CAPTURE(W);
    const int H = 4, n = H * W;
    Tensor x = Tensor::full({1, 1, H, W}, 3.0f);
    auto g = testing::random_normal(n / 4, 30);
    auto dx = nn::maxpool2x2_backward(x, Tensor::from_host(g, {1, 1, H / 2, W / 2})).to_host();
    REQUIRE(testing::all_finite(dx));
    for (int oy = 0; oy < H / 2; ++oy)
      for (int ox = 0; ox < W / 2; ++ox) {
        const float d00 = dx[2 * oy * W + 2 * ox], d01 = dx[2 * oy * W + 2 * ox + 1];
        const float d10 = dx[(2 * oy + 1) * W + 2 * ox], d11 = dx[(2 * oy + 1) * W + 2 * ox + 1];
        CHECK(d00 == g[oy * (W / 2) + ox]);  // sum preserved, all of it on the first element
        CHECK(d01 == 0.0f);
        CHECK(d10 == 0.0f);
        CHECK(d11 == 0.0f);
      }
    // Partial ties: window (1, 3, 3, 2) -> (0,1); (1, 2, 3, 3) -> (1,0); (0, 0, 0, 5) -> (1,1).
    std::vector<float> v(n, 0.0f);
    auto set = [&](int ox, float a, float b, float c, float d) {
      v[2 * ox] = a, v[2 * ox + 1] = b, v[W + 2 * ox] = c, v[W + 2 * ox + 1] = d;
    };
    set(0, 1, 3, 3, 2);
    set(1, 1, 2, 3, 3);
    set(2, 0, 0, 0, 5);
    auto d = nn::maxpool2x2_backward(Tensor::from_host(v, {1, 1, H, W}), Tensor::full({1, 1, H / 2, W / 2}, 1.0f))
                 .to_host();
    CHECK(d[1] == 1.0f);
    CHECK(d[0] + d[W] + d[W + 1] == 0.0f);
    CHECK(d[W + 2] == 1.0f);
    CHECK(d[2] + d[3] + d[W + 3] == 0.0f);
    CHECK(d[W + 5] == 1.0f);
    CHECK(d[4] + d[5] + d[W + 4] == 0.0f);
  }
}

TEST_CASE("maxpool2x2 with extreme magnitudes") {
  std::vector<float> x = {-1e30f, -2e30f, -3e30f, -4e30f, 1e-30f, 2e-30f, -1e-30f, 1.5e-30f};
  Tensor tx = Tensor::from_host(x, {1, 1, 2, 4});
  auto y = nn::maxpool2x2_forward(tx).to_host();
  check_close(y, ref_pool(to_double(x), 1, 2, 4), 0.0, 0.0, "maxpool extreme (exact)");
  auto dx = nn::maxpool2x2_backward(tx, Tensor::full({1, 1, 1, 2}, 1e30f)).to_host();
  // Window 0 is (-1e30, -2e30, 1e-30, 2e-30), window 1 (-3e30, -4e30, -1e-30, 1.5e-30).
  CHECK(dx[5] == 1e30f);
  CHECK(dx[7] == 1e30f);
  CHECK(dx[0] + dx[1] + dx[2] + dx[3] + dx[4] + dx[6] == 0.0f);
  CHECK(testing::all_finite(dx));
}

TEST_CASE("upsample2x forward and backward") {
  // W = 11: one 8-wide group plus a tail of 3.
  const int N = 2, C = 2, H = 3, W = 11;
  auto x = testing::random_normal(size_t(N) * C * H * W, 40);
  auto g = testing::random_normal(size_t(N) * C * 4 * H * W, 41);
  Tensor tx = Tensor::from_host(x, {N, C, H, W});
  Tensor y = nn::upsample2x_forward(tx);
  CHECK(y.shape() == Shape{N, C, 2 * H, 2 * W});
  check_close(y.to_host(), ref_upsample(to_double(x), N * C, H, W), 0.0, 0.0, "upsample forward (exact)");
  Tensor dx = nn::upsample2x_backward(Tensor::from_host(g, {N, C, 2 * H, 2 * W}));
  CHECK(dx.shape() == Shape{N, C, H, W});
  auto gd = to_double(g);
  auto f = [&](const std::vector<double>& v) { return testing::dot(gd, ref_upsample(v, N * C, H, W)); };
  // Linear: the differences are exact to double rounding; the kernel sums 4 floats (rtol 1e-6).
  check_close(dx.to_host(), testing::finite_difference(f, to_double(x), 1e-2), 1e-6, 1e-6, "upsample backward");
}

TEST_CASE("upsample2x with extreme magnitudes: sums of 4 x 1e37 and 4 x 1e-30 stay finite") {
  Tensor big = Tensor::full({1, 1, 4, 18}, 1e37f), tiny = Tensor::full({1, 1, 4, 18}, 1e-30f);
  for (float v : nn::upsample2x_backward(big).to_host()) CHECK(v == doctest::Approx(4e37f).epsilon(1e-6));
  for (float v : nn::upsample2x_backward(tiny).to_host()) CHECK(v == doctest::Approx(4e-30f).epsilon(1e-6).scale(0));
  for (float v : nn::upsample2x_forward(tiny).to_host()) CHECK(v == 1e-30f);
}

TEST_CASE("spatial ops: bad shapes give clear errors") {
  std::string e = error_of([] { nn::maxpool2x2_forward(Tensor::zeros({1, 2, 1, 4})); });
  CHECK(e.find("H and W >= 2") != std::string::npos);
  CHECK(e.find("[1, 2, 1, 4]") != std::string::npos);
  e = error_of([] { nn::maxpool2x2_backward(Tensor::zeros({1, 2, 5, 1}), Tensor::zeros({1, 2, 2, 1})); });
  CHECK(e.find("H and W >= 2") != std::string::npos);
  e = error_of([] { nn::maxpool2x2_backward(Tensor::zeros({1, 2, 5, 5}), Tensor::zeros({1, 2, 3, 3})); });
  CHECK(e.find("dy") != std::string::npos);  // odd sizes floor: dy must be [1, 2, 2, 2]
  e = error_of([] { nn::maxpool2x2_backward(Tensor::zeros({1, 2, 4, 4}), Tensor::zeros({1, 2, 2, 3})); });
  CHECK(e.find("dy") != std::string::npos);
  e = error_of([] { nn::upsample2x_forward(Tensor::zeros({2, 4, 4})); });
  CHECK(e.find("[N,C,H,W]") != std::string::npos);
  e = error_of([] { nn::upsample2x_backward(Tensor::zeros({1, 1, 3, 4})); });
  CHECK(e.find("even H and W") != std::string::npos);
  e = error_of([] { nn::relu_backward(Tensor::zeros({1, 1, 2, 2}), Tensor::zeros({1, 1, 2, 3})); });
  CHECK(e.find("dy") != std::string::npos);
}

// ---- polyphase 2x2 max pooling and its interleave -------------------------------------------------
namespace {
// [N, C, H, W] -> [4N, C, H/2, W/2] in double: block 2a + b is the pool moved by (a, b).
std::vector<double> ref_pool_phases(const std::vector<double>& x, int N, int C, int H, int W) {
  const size_t plane = size_t(H / 2) * (W / 2);
  std::vector<double> y(4 * size_t(N) * C * plane);
  for (int ph = 0; ph < 4; ++ph)
    for (int p = 0; p < N * C; ++p)
      for (int i = 0; i < H / 2; ++i)
        for (int j = 0; j < W / 2; ++j) {
          const int y0 = 2 * i + ph / 2, x0 = 2 * j + ph % 2, y1 = std::min(y0 + 1, H - 1), x1 = std::min(x0 + 1, W - 1);
          auto at = [&](int yy, int xx) { return x[(size_t(p) * H + yy) * W + xx]; };
          y[(size_t(ph) * N * C + p) * plane + size_t(i) * (W / 2) + j] =
              std::max(std::max(at(y0, x0), at(y0, x1)), std::max(at(y1, x0), at(y1, x1)));
        }
  return y;
}
}  // namespace

TEST_CASE("maxpool2x2 phases: forward against a double reference, backward against finite differences") {
  // 2 x 2 (every window of phases 1..3 is clamped), 4 x 6, 6 x 10 (interior windows that overlap).
  const int sizes[][2] = {{2, 2}, {4, 6}, {6, 10}};
  for (const auto& hw : sizes) {
    const int N = 2, C = 3, H = hw[0], W = hw[1];
    CAPTURE(H);
    CAPTURE(W);
    auto x = away_from_kinks(size_t(N) * C * H * W, 40 + W);
    Tensor tx = Tensor::from_host(x, {N, C, H, W});
    Tensor y = nn::maxpool2x2_phases_forward(tx);
    REQUIRE(y.shape() == Shape{4 * N, C, H / 2, W / 2});
    check_close(y.to_host(), ref_pool_phases(to_double(x), N, C, H, W), 0.0, 0.0, "phases forward (exact)");
    // Phase (0, 0) is the ordinary stride-2 pool.
    const auto yv = y.to_host();
    const auto p0 = nn::maxpool2x2_forward(tx).to_host();
    CHECK(std::equal(p0.begin(), p0.end(), yv.begin()));

    auto g = testing::random_normal(yv.size(), 50 + W);
    const auto gd = to_double(g);
    Tensor dx = nn::maxpool2x2_phases_backward(tx, Tensor::from_host(g, y.shape()));
    auto f = [&](const std::vector<double>& v) { return testing::dot(gd, ref_pool_phases(v, N, C, H, W)); };
    check_close(dx.to_host(), testing::finite_difference(f, to_double(x), 1e-3), 1e-6, 1e-6, "phases backward");
  }
}

TEST_CASE("maxpool2x2 phases: ties and clamped windows send each window's gradient to one element") {
  // A constant input: every window's maximum is a tie; the sum of dy must arrive exactly once each.
  const int H = 4, W = 6;
  Tensor x = Tensor::full({1, 1, H, W}, -2.5f);
  auto g = testing::random_normal(size_t(4 * (H / 2) * (W / 2)), 60);
  auto dx = nn::maxpool2x2_phases_backward(x, Tensor::from_host(g, {4, 1, H / 2, W / 2})).to_host();
  REQUIRE(testing::all_finite(dx));
  double sg = 0, sd = 0;
  for (float v : g) sg += v;
  for (float v : dx) sd += v;
  CHECK(sd == doctest::Approx(sg).epsilon(1e-6));
  // First maximum in row-major order: a window at (oy, ox) gives all of its dy to (oy, ox), so every pixel
  // gets exactly the dy of the window starting on it.
  for (int oy = 0; oy < H; ++oy)
    for (int ox = 0; ox < W; ++ox) {
      const int ph = (oy % 2) * 2 + ox % 2;
      CHECK(dx[size_t(oy * W + ox)] == g[size_t(ph * (H / 2) * (W / 2) + (oy / 2) * (W / 2) + ox / 2)]);
    }
  // Extreme magnitudes stay exact (max and a sum of at most 4 terms of one sign).
  std::vector<float> big = {1e30f, -1e30f, 3e30f, 2e-30f, -1e-30f, 1e30f, 5e29f, -3e30f};
  Tensor tb = Tensor::from_host(big, {1, 1, 2, 4});
  check_close(nn::maxpool2x2_phases_forward(tb).to_host(), ref_pool_phases(to_double(big), 1, 1, 2, 4), 0.0, 0.0,
              "phases extreme (exact)");
  CHECK(testing::all_finite(nn::maxpool2x2_phases_backward(tb, Tensor::full({4, 1, 1, 2}, 1e37f)).to_host()));
}

TEST_CASE("phase interleave: a permutation whose backward is its transpose") {
  const int N = 2, C = 3, h = 3, w = 5;
  auto x = testing::random_normal(size_t(4 * N * C * h * w), 70);
  Tensor y = nn::phase_interleave_forward(Tensor::from_host(x, {4 * N, C, h, w}));
  REQUIRE(y.shape() == Shape{N, C, 2 * h, 2 * w});
  const auto yv = y.to_host();
  for (int n = 0; n < N; ++n)
    for (int c = 0; c < C; ++c)
      for (int yy = 0; yy < 2 * h; ++yy)
        for (int xx = 0; xx < 2 * w; ++xx) {
          const int ph = (yy % 2) * 2 + xx % 2;
          CHECK(yv[((size_t(n) * C + c) * 2 * h + yy) * 2 * w + xx] ==
                x[((size_t(ph) * N + n) * C + c) * h * w + size_t(yy / 2) * w + xx / 2]);
        }
  // The backward undoes the forward exactly, and <g, P x> = <P^T g, x>.
  const auto back = nn::phase_interleave_backward(y).to_host();
  CHECK(back == x);
  auto g = testing::random_normal(yv.size(), 71);
  const auto pg = nn::phase_interleave_backward(Tensor::from_host(g, y.shape())).to_host();
  CHECK(testing::dot(to_double(g), to_double(yv)) == doctest::Approx(testing::dot(to_double(pg), to_double(x))));
}

TEST_CASE("polyphase ops refuse shapes they cannot take, naming them") {
  CHECK(error_of([] { nn::maxpool2x2_phases_forward(Tensor::zeros({1, 2, 5, 4})); }).find("even") != std::string::npos);
  CHECK(error_of([] { nn::maxpool2x2_phases_backward(Tensor::zeros({1, 2, 4, 4}), Tensor::zeros({1, 2, 2, 2})); })
            .find("dy") != std::string::npos);
  CHECK(error_of([] { nn::phase_interleave_forward(Tensor::zeros({6, 2, 3, 3})); }).find("[6, 2, 3, 3]") !=
        std::string::npos);
  CHECK(error_of([] { nn::phase_interleave_backward(Tensor::zeros({1, 2, 3, 4})); }).find("even") != std::string::npos);
}
