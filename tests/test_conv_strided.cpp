// The general strided ops (kernels/strided.cl): conv2d with a k x k kernel, stride s and zero padding p,
// and k x k max pooling with stride s. Forward against a double-precision CPU reference written from
// torch's definitions, backward (dx, dw, db; pooling dx) against central differences of that reference,
// odd and out-of-range shapes (AlexNet's 11x11 / 4 / 2 on 37x53, 1x1 outputs, padding wider than the
// kernel, rows and columns the flooring leaves out), the row-chunked path, and the refused shapes.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <string>
#include <vector>

#include "host/error.hpp"
#include "lib/nn/ops.hpp"
#include "tests/testing.hpp"

using namespace stylerf;
using host::Shape;
using host::Tensor;
using testing::check_close;
using testing::error_of;
using testing::to_double;

namespace {

struct Case {
  int N, Cin, Cout, H, W, K, S, P;
  bool bias;
  int Ho() const { return (H + 2 * P - K) / S + 1; }
  int Wo() const { return (W + 2 * P - K) / S + 1; }
};

std::string name(const Case& c) {
  return "N=" + std::to_string(c.N) + " Cin=" + std::to_string(c.Cin) + " Cout=" + std::to_string(c.Cout) +
         " H=" + std::to_string(c.H) + " W=" + std::to_string(c.W) + " k=" + std::to_string(c.K) +
         " s=" + std::to_string(c.S) + " p=" + std::to_string(c.P) + (c.bias ? " bias" : "");
}

// torch's Conv2d(stride=S, padding=P), in double:
// y[n,co,oy,ox] = b[co] + sum_{ci,ky,kx} w[co,ci,ky,kx] * x[n,ci,oy*S+ky-P,ox*S+kx-P] (0 outside).
std::vector<double> ref_conv(const Case& c, const std::vector<double>& x, const std::vector<double>& w,
                             const std::vector<double>& b) {
  const int Ho = c.Ho(), Wo = c.Wo();
  std::vector<double> y(size_t(c.N) * c.Cout * Ho * Wo, 0.0);
  for (int n = 0; n < c.N; ++n)
    for (int co = 0; co < c.Cout; ++co)
      for (int oy = 0; oy < Ho; ++oy)
        for (int ox = 0; ox < Wo; ++ox) {
          double s = c.bias ? b[co] : 0.0;
          for (int ci = 0; ci < c.Cin; ++ci)
            for (int ky = 0; ky < c.K; ++ky) {
              const int sy = oy * c.S + ky - c.P;
              if (sy < 0 || sy >= c.H) continue;
              for (int kx = 0; kx < c.K; ++kx) {
                const int sx = ox * c.S + kx - c.P;
                if (sx < 0 || sx >= c.W) continue;
                s += w[((size_t(co) * c.Cin + ci) * c.K + ky) * c.K + kx] *
                     x[((size_t(n) * c.Cin + ci) * c.H + sy) * c.W + sx];
              }
            }
          y[((size_t(n) * c.Cout + co) * Ho + oy) * Wo + ox] = s;
        }
  return y;
}

struct Data {
  std::vector<float> x, w, b, dy;
};

Data make_data(const Case& c, uint64_t seed) {
  Data d;
  d.x = testing::random_normal(size_t(c.N) * c.Cin * c.H * c.W, seed);
  d.w = testing::random_normal(size_t(c.Cout) * c.Cin * c.K * c.K, seed + 1);
  d.b = testing::random_normal(size_t(c.Cout), seed + 2);
  d.dy = testing::random_normal(size_t(c.N) * c.Cout * c.Ho() * c.Wo(), seed + 3);
  return d;
}

Tensor x_of(const Case& c, const Data& d) { return Tensor::from_host(d.x, {c.N, c.Cin, c.H, c.W}); }
Tensor w_of(const Case& c, const Data& d) { return Tensor::from_host(d.w, {c.Cout, c.Cin, c.K, c.K}); }

std::vector<float> run_forward(const Case& c, const Data& d) {
  Tensor b = c.bias ? Tensor::from_host(d.b, {c.Cout}) : Tensor();
  Tensor y = nn::conv2d_strided_forward(x_of(c, d), w_of(c, d), b, c.S, c.P);
  CHECK(y.shape() == Shape{c.N, c.Cout, c.Ho(), c.Wo()});
  return y.to_host();
}

// Tolerance: float sums of Cin*k*k <= 363 unit-scale products (errors ~1e-6 of the sum of |terms|, which
// is ~20): rtol / atol 1e-4 leave margin while one wrong tap (an O(1) error) fails.
void check_forward(const Case& c, uint64_t seed) {
  const Data d = make_data(c, seed);
  check_close(run_forward(c, d), ref_conv(c, to_double(d.x), to_double(d.w), to_double(d.b)), 1e-4, 1e-4,
              "conv2d_strided_forward " + name(c));
}

// L = <dy, conv(x, w, b)> is linear in each argument: central differences with h = 1e-2 are exact up to
// double rounding. At most `probe` entries of x and w are probed.
void check_backward(const Case& c, uint64_t seed, size_t probe = 300) {
  const Data d = make_data(c, seed);
  const auto xd = to_double(d.x), wd = to_double(d.w), bd = to_double(d.b), gd = to_double(d.dy);
  const Tensor dy = Tensor::from_host(d.dy, {c.N, c.Cout, c.Ho(), c.Wo()});
  const auto g = nn::conv2d_strided_backward(x_of(c, d), w_of(c, d), dy, c.S, c.P, true, true);
  REQUIRE(g.dx.defined());
  REQUIRE(g.dw.defined());
  REQUIRE(g.db.defined());
  CHECK(g.dx.shape() == Shape{c.N, c.Cin, c.H, c.W});
  auto sample = [&](size_t n) {
    std::vector<size_t> idx;
    const size_t step = std::max<size_t>(1, n / probe);
    for (size_t i = 0; i < n; i += step) idx.push_back(i);
    return idx;
  };
  auto pick = [](const std::vector<float>& v, const std::vector<size_t>& idx) {
    std::vector<float> out;
    for (size_t i : idx) out.push_back(v[i]);
    return out;
  };
  const auto xi = sample(xd.size()), wi = sample(wd.size());
  auto fx = [&](const std::vector<double>& v) { return testing::dot(gd, ref_conv(c, v, wd, bd)); };
  auto fw = [&](const std::vector<double>& v) { return testing::dot(gd, ref_conv(c, xd, v, bd)); };
  check_close(pick(g.dx.to_host(), xi), testing::finite_difference_at(fx, xd, xi, 1e-2), 1e-4, 1e-4,
              "conv2d_strided dx " + name(c));
  check_close(pick(g.dw.to_host(), wi), testing::finite_difference_at(fw, wd, wi, 1e-2), 1e-4, 1e-4,
              "conv2d_strided dw " + name(c));
  Case cb = c;
  cb.bias = true;
  auto fb = [&](const std::vector<double>& v) { return testing::dot(gd, ref_conv(cb, xd, wd, v)); };
  check_close(g.db.to_host(), testing::finite_difference(fb, bd, 1e-2), 1e-4, 1e-4, "conv2d_strided db " + name(c));
}

// Sets STYLERF_CONV_SCRATCH_BYTES for the scope (forces the row-chunked path).
struct ScratchLimit {
  explicit ScratchLimit(size_t bytes) { setenv("STYLERF_CONV_SCRATCH_BYTES", std::to_string(bytes).c_str(), 1); }
  ~ScratchLimit() { unsetenv("STYLERF_CONV_SCRATCH_BYTES"); }
};

// torch's MaxPool2d(k, s), in double, planes [NC][H][W].
std::vector<double> ref_pool(const std::vector<double>& x, int nc, int H, int W, int k, int s) {
  const int Ho = (H - k) / s + 1, Wo = (W - k) / s + 1;
  std::vector<double> y(size_t(nc) * Ho * Wo);
  for (int p = 0; p < nc; ++p)
    for (int oy = 0; oy < Ho; ++oy)
      for (int ox = 0; ox < Wo; ++ox) {
        double m = -INFINITY;
        for (int ky = 0; ky < k; ++ky)
          for (int kx = 0; kx < k; ++kx) m = std::max(m, x[(size_t(p) * H + oy * s + ky) * W + ox * s + kx]);
        y[(size_t(p) * Ho + oy) * Wo + ox] = m;
      }
  return y;
}

}  // namespace

// ---- conv2d_strided -------------------------------------------------------------------------------

TEST_CASE("conv2d_output_size floors like torch") {
  CHECK(nn::conv2d_output_size(256, 11, 4, 2) == 63);  // AlexNet conv1 at 256
  CHECK(nn::conv2d_output_size(37, 11, 4, 2) == 8);
  CHECK(nn::conv2d_output_size(53, 11, 4, 2) == 12);
  CHECK(nn::conv2d_output_size(7, 11, 4, 2) == 1);
  CHECK(nn::conv2d_output_size(6, 11, 4, 2) == 0);  // no output position
  CHECK(nn::conv2d_output_size(5, 3, 1, 1) == 5);
}

TEST_CASE("conv2d_strided forward matches the double reference") {
  uint64_t seed = 10;
  const Case cases[] = {
      {1, 3, 4, 37, 53, 11, 4, 2, true},  // AlexNet conv1 on an odd size: 8 x 12 out, the last input rows unread
      {2, 3, 5, 9, 8, 5, 1, 2, false},    // 5x5 "same" (AlexNet conv2), N = 2
      {1, 2, 3, 7, 19, 3, 1, 1, true},    // stride 1: the 8-wide im2col path with both borders
      {1, 2, 3, 9, 41, 3, 2, 1, true},    // stride 2: the vload16 path and a scalar tail
      {1, 2, 3, 5, 15, 3, 2, 1, true},    // stride 2, 8 columns ending at W - 1: the vload16 guard (scalar)
      {1, 2, 3, 10, 40, 4, 2, 0, false},  // even k, no padding
      {1, 3, 2, 6, 7, 1, 1, 0, true},     // 1x1
      {1, 3, 2, 6, 7, 1, 3, 0, true},     // 1x1 stride 3: the last rows / columns skipped
      {1, 2, 3, 4, 5, 2, 3, 3, true},     // padding wider than the kernel: all-padding outputs are the bias
      {1, 2, 2, 3, 3, 3, 1, 0, false},    // 1x1 output
      {1, 2, 2, 7, 7, 11, 4, 2, true},    // AlexNet conv1 at its smallest input: 1x1 output
      {1, 1, 1, 1, 1, 3, 2, 1, true},     // 1x1 input, 1x1 output (only the centre tap is inside)
  };
  for (const Case& c : cases) check_forward(c, seed++);
}

TEST_CASE("conv2d_strided backward dx, dw, db match finite differences") {
  uint64_t seed = 100;
  const Case cases[] = {
      {1, 2, 3, 37, 53, 11, 4, 2, false},  // dx of the rows / columns no window reads is 0
      {2, 3, 4, 9, 8, 5, 1, 2, true},
      {1, 2, 3, 7, 19, 3, 1, 1, false},  // the 8-wide col2im path
      {1, 2, 3, 9, 41, 3, 2, 1, false},
      {1, 2, 2, 10, 9, 4, 2, 0, false},
      {1, 3, 2, 6, 7, 1, 3, 0, false},
      {1, 2, 3, 4, 5, 2, 3, 3, false},
      {1, 2, 2, 7, 7, 11, 4, 2, false},
  };
  for (const Case& c : cases) check_backward(c, seed++);
}

TEST_CASE("conv2d_strided equals conv2d (im2col) for stride 1, zero 'same' padding") {
  // Same algorithm on both sides, so the results agree to float rounding of the same sums.
  Case c{2, 5, 6, 11, 13, 3, 1, 1, true};
  const Data d = make_data(c, 150);
  Tensor x = x_of(c, d), w = w_of(c, d), b = Tensor::from_host(d.b, {c.Cout});
  check_close(nn::conv2d_strided_forward(x, w, b, 1, 1).to_host(),
              to_double(nn::conv2d_forward(x, w, b, nn::Padding::Zero, nn::ConvAlgo::Im2col).to_host()), 1e-6, 1e-6, "strided vs conv2d");
}

TEST_CASE("conv2d_strided row-chunked path (scratch smaller than one image's col) matches") {
  // 11x11/4/2 on 37x53 with Cin = 2: Cin*k*k = 242, Wo = 12: 11616 bytes a row; 25000 bytes gives 2-row
  // chunks (4 of them for Ho = 8) whose input rows overlap by 7 (the accumulating col2im).
  {
    ScratchLimit limit(25000);
    Case c{1, 2, 3, 37, 53, 11, 4, 2, true};
    check_forward(c, 200);
    check_backward(c, 201);
    Case c2{2, 2, 3, 9, 19, 3, 1, 1, true};  // one-row chunks, the 8-wide col2im adding
    ScratchLimit one_row(size_t(2) * 9 * 19 * 4 + 4);
    check_forward(c2, 202);
    check_backward(c2, 203);
  }
  ScratchLimit tiny(100);
  Case c{1, 3, 5, 7, 6, 3, 1, 1, false};
  CHECK(error_of([&] { run_forward(c, make_data(c, 204)); }).find("scratch limit") != std::string::npos);
}

TEST_CASE("conv2d_strided backward computes only what is asked for") {
  Case c{1, 2, 3, 13, 11, 5, 2, 1, false};
  const Data d = make_data(c, 300);
  Tensor x = x_of(c, d), w = w_of(c, d), dy = Tensor::from_host(d.dy, {c.N, c.Cout, c.Ho(), c.Wo()});
  auto only_dx = nn::conv2d_strided_backward(x, w, dy, c.S, c.P, true, false);
  auto only_params = nn::conv2d_strided_backward(x, w, dy, c.S, c.P, false, true);
  auto both = nn::conv2d_strided_backward(x, w, dy, c.S, c.P, true, true);
  CHECK(!only_dx.dw.defined());
  CHECK(!only_params.dx.defined());
  CHECK(only_dx.dx.to_host() == both.dx.to_host());
  CHECK(only_params.dw.to_host() == both.dw.to_host());
}

TEST_CASE("conv2d_strided bad shapes give clear errors") {
  Tensor w11 = Tensor::zeros({4, 3, 11, 11});
  // k > H + 2p: 11 > 6 + 4.
  std::string e = error_of([&] { nn::conv2d_strided_forward(Tensor::zeros({1, 3, 6, 40}), w11, Tensor(), 4, 2); });
  CHECK(e.find("11x11 kernel is larger than the input 6x40") != std::string::npos);
  CHECK(e.find("(10x44)") != std::string::npos);
  e = error_of([&] {
    nn::conv2d_strided_backward(Tensor::zeros({1, 3, 40, 6}), w11, Tensor::zeros({1, 4, 9, 1}), 4, 2, true, true);
  });
  CHECK(e.find("larger than the input 40x6") != std::string::npos);
  e = error_of([&] { nn::conv2d_strided_forward(Tensor::zeros({1, 3, 40, 40}), w11, Tensor(), 0, 2); });
  CHECK(e.find("stride must be >= 1") != std::string::npos);
  e = error_of([&] { nn::conv2d_strided_forward(Tensor::zeros({1, 3, 40, 40}), w11, Tensor(), 4, -1); });
  CHECK(e.find("padding must be >= 0") != std::string::npos);
  e = error_of([&] { nn::conv2d_strided_forward(Tensor::zeros({1, 2, 40, 40}), w11, Tensor(), 4, 2); });
  CHECK(e.find("channel mismatch") != std::string::npos);
  e = error_of(
      [&] { nn::conv2d_strided_forward(Tensor::zeros({1, 3, 40, 40}), Tensor::zeros({4, 3, 3, 5}), Tensor(), 1, 1); });
  CHECK(e.find("[Cout,Cin,k,k]") != std::string::npos);
  e = error_of([&] { nn::conv2d_strided_forward(Tensor::zeros({1, 3, 40, 40}), w11, Tensor::zeros({3}), 4, 2); });
  CHECK(e.find("bias") != std::string::npos);
  e = error_of([&] {
    nn::conv2d_strided_backward(Tensor::zeros({1, 3, 40, 40}), w11, Tensor::zeros({1, 4, 9, 8}), 4, 2, true, true);
  });
  CHECK(e.find("dy") != std::string::npos);  // (40 + 4 - 11) / 4 + 1 = 9
  e = error_of([&] { nn::conv2d_strided_forward(Tensor::zeros({3, 40, 40}), w11, Tensor(), 4, 2); });
  CHECK(e.find("[N,Cin,H,W]") != std::string::npos);
}

// ---- k x k max pooling ----------------------------------------------------------------------------

TEST_CASE("maxpool k x k stride s: forward exact, backward matches finite differences") {
  struct P {
    int N, C, H, W, k, s;
  };
  // AlexNet's 3x3/2 (overlapping windows) on odd and even sizes (floor: 16 -> 7, the last row unread),
  // 2x2/2 (as maxpool2x2), 3x3/3, 2x2/1, 1x1/2, a window as large as the input (1x1 output), 4x3 planes.
  for (P p : {P{1, 2, 15, 15, 3, 2}, P{2, 3, 16, 9, 3, 2}, P{1, 2, 6, 8, 2, 2}, P{1, 1, 9, 10, 3, 3},
              P{1, 2, 5, 6, 2, 1}, P{1, 2, 5, 6, 1, 2}, P{1, 2, 4, 4, 4, 2}, P{1, 1, 3, 3, 3, 2}}) {
    CAPTURE(p.H);
    CAPTURE(p.W);
    CAPTURE(p.k);
    CAPTURE(p.s);
    const int Ho = (p.H - p.k) / p.s + 1, Wo = (p.W - p.k) / p.s + 1, nc = p.N * p.C;
    // Random values: distinct with probability 1, so the maximum is unique and the function smooth.
    const auto x = testing::random_normal(size_t(nc) * p.H * p.W, 400 + p.H * 7 + p.k);
    const auto g = testing::random_normal(size_t(nc) * Ho * Wo, 500 + p.W);
    Tensor tx = Tensor::from_host(x, {p.N, p.C, p.H, p.W});
    Tensor y = nn::maxpool_forward(tx, p.k, p.s);
    CHECK(y.shape() == Shape{p.N, p.C, Ho, Wo});
    check_close(y.to_host(), ref_pool(to_double(x), nc, p.H, p.W, p.k, p.s), 0.0, 0.0, "maxpool forward (exact)");
    Tensor dx = nn::maxpool_backward(tx, Tensor::from_host(g, {p.N, p.C, Ho, Wo}), p.k, p.s);
    CHECK(dx.shape() == tx.shape());
    const auto gd = to_double(g);
    auto f = [&](const std::vector<double>& v) { return testing::dot(gd, ref_pool(v, nc, p.H, p.W, p.k, p.s)); };
    check_close(dx.to_host(), testing::finite_difference(f, to_double(x), 1e-4), 1e-6, 1e-6, "maxpool backward");
  }
}

TEST_CASE("maxpool k x k: 2x2/2 agrees with maxpool2x2 (forward, backward with ties)") {
  const int H = 9, W = 21;
  auto x = testing::random_uniform(size_t(2) * H * W, 600, 0.0f, 1.0f);
  for (size_t i = 0; i < x.size(); i += 3) x[i] = std::round(x[i] * 2.0f);  // many ties
  const auto g = testing::random_normal(size_t(2) * (H / 2) * (W / 2), 601);
  Tensor tx = Tensor::from_host(x, {1, 2, H, W}), tg = Tensor::from_host(g, {1, 2, H / 2, W / 2});
  CHECK(nn::maxpool_forward(tx, 2, 2).to_host() == nn::maxpool2x2_forward(tx).to_host());
  CHECK(nn::maxpool_backward(tx, tg, 2, 2).to_host() == nn::maxpool2x2_backward(tx, tg).to_host());
}

TEST_CASE("maxpool k x k ties: each window's gradient goes to its first maximum; overlaps add up") {
  // A constant 5x5 plane, 3x3/2: windows at (0,0), (0,2), (2,0), (2,2); each one's first maximum is its
  // top-left element.
  const int H = 5, W = 5;
  const std::vector<float> g = {1.0f, 2.0f, 3.0f, 4.0f};
  auto dx = nn::maxpool_backward(Tensor::full({1, 1, H, W}, 7.0f), Tensor::from_host(g, {1, 1, 2, 2}), 3, 2).to_host();
  std::vector<float> want(H * W, 0.0f);
  want[0] = 1.0f, want[2] = 2.0f, want[2 * W] = 3.0f, want[2 * W + 2] = 4.0f;
  CHECK(dx == want);
  // One peak in the shared centre of all four windows gets the sum of their gradients.
  std::vector<float> x(H * W, 0.0f);
  x[2 * W + 2] = 1.0f;
  dx = nn::maxpool_backward(Tensor::from_host(x, {1, 1, H, W}), Tensor::from_host(g, {1, 1, 2, 2}), 3, 2).to_host();
  CHECK(dx[2 * W + 2] == 10.0f);
  float rest = 0.0f;
  for (int i = 0; i < H * W; ++i)
    if (i != 2 * W + 2) rest += std::fabs(dx[i]);
  CHECK(rest == 0.0f);
}

TEST_CASE("maxpool k x k with extreme magnitudes") {
  std::vector<float> x = {-1e30f, -2e30f, -3e30f, 1e-30f, 2e-30f, -1e-30f, 1e38f, -1e38f, 3e-29f};
  Tensor tx = Tensor::from_host(x, {1, 1, 3, 3});
  auto y = nn::maxpool_forward(tx, 2, 1).to_host();
  check_close(y, ref_pool(to_double(x), 1, 3, 3, 2, 1), 0.0, 0.0, "maxpool extreme (exact)");
  auto dx = nn::maxpool_backward(tx, Tensor::full({1, 1, 2, 2}, 1e30f), 2, 1).to_host();
  REQUIRE(testing::all_finite(dx));
  // Windows: (-1e30,-2e30,1e-30,2e-30) -> 2e-30 [4]; (-2e30,-3e30,2e-30,-1e-30) -> 2e-30 [4];
  // (1e-30,2e-30,1e38,-1e38) -> 1e38 [6]; (2e-30,-1e-30,-1e38,3e-29) -> 3e-29 [8].
  CHECK(dx[4] == 2e30f);
  CHECK(dx[6] == 1e30f);
  CHECK(dx[8] == 1e30f);
}

TEST_CASE("maxpool k x k bad shapes give clear errors") {
  std::string e = error_of([] { nn::maxpool_forward(Tensor::zeros({1, 2, 2, 9}), 3, 2); });
  CHECK(e.find("3x3 pooling needs H and W >= 3") != std::string::npos);
  CHECK(e.find("[1, 2, 2, 9]") != std::string::npos);
  e = error_of([] { nn::maxpool_forward(Tensor::zeros({1, 2, 5, 5}), 0, 2); });
  CHECK(e.find("window and stride must be >= 1") != std::string::npos);
  e = error_of([] { nn::maxpool_forward(Tensor::zeros({1, 2, 5, 5}), 3, 0); });
  CHECK(e.find("window and stride must be >= 1") != std::string::npos);
  e = error_of([] { nn::maxpool_backward(Tensor::zeros({1, 2, 15, 15}), Tensor::zeros({1, 2, 8, 8}), 3, 2); });
  CHECK(e.find("dy") != std::string::npos);  // floor: (15 - 3) / 2 + 1 = 7
  e = error_of([] { nn::maxpool_forward(Tensor::zeros({2, 5, 5}), 3, 2); });
  CHECK(e.find("[N,C,H,W]") != std::string::npos);
}
