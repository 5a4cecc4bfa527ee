// conv2d, every algorithm (im2col + GEMM with the col2im gather; Winograd F(2x2,3x3) and F(4x4,3x3) with
// their transforms' adjoints): forward against a double-precision CPU reference, backward (dx, dw, db)
// against central finite differences of that reference, hard magnitudes, odd and edge shapes (partial
// Winograd tiles), the row-chunked path, and the error messages for bad shapes.
#include <doctest/doctest.h>

#include <cmath>
#include <cstdlib>
#include <string>
#include <vector>

#include "host/error.hpp"
#include "lib/nn/ops.hpp"
#include "tests/testing.hpp"

using namespace stylerf;
using testing::error_of;
using nn::Padding;
using host::Tensor;
using testing::check_close;
using testing::to_double;

namespace {

struct Case {
  int N, Cin, Cout, H, W, K;
  Padding pad;
  bool bias;
};

// The algorithm run_forward / run_backward ask for; each test loops over kAlgos with ForAlgo.
nn::ConvAlgo g_algo = nn::ConvAlgo::Im2col;
const nn::ConvAlgo kAlgos[] = {nn::ConvAlgo::Im2col, nn::ConvAlgo::Winograd2, nn::ConvAlgo::Winograd4};

std::string name(const Case& c) {
  return std::string(nn::conv_algo_name(g_algo)) + " N=" + std::to_string(c.N) + " Cin=" + std::to_string(c.Cin) + " Cout=" + std::to_string(c.Cout) +
         " H=" + std::to_string(c.H) + " W=" + std::to_string(c.W) + " k=" + std::to_string(c.K) +
         (c.pad == Padding::Reflect ? " reflect" : " zero") + (c.bias ? " bias" : "");
}

// Index into the padded input: PyTorch ReflectionPad2d / zero padding. Returns -1 for a zero tap.
int source_index(int i, int n, Padding pad) {
  if (i >= 0 && i < n) return i;
  if (pad == Padding::Zero) return -1;
  return i < 0 ? -i : 2 * n - 2 - i;
}

// Direct convolution in double: y[n,co,y,x] = b[co] + sum_{ci,ky,kx} w[co,ci,ky,kx] * xpad[n,ci,y+ky-p,x+kx-p].
std::vector<double> ref_conv(const Case& c, const std::vector<double>& x, const std::vector<double>& w,
                             const std::vector<double>& b) {
  const int p = c.K / 2;
  std::vector<double> y(size_t(c.N) * c.Cout * c.H * c.W, 0.0);
  for (int n = 0; n < c.N; ++n)
    for (int co = 0; co < c.Cout; ++co)
      for (int yy = 0; yy < c.H; ++yy)
        for (int xx = 0; xx < c.W; ++xx) {
          double s = c.bias ? b[co] : 0.0;
          for (int ci = 0; ci < c.Cin; ++ci)
            for (int ky = 0; ky < c.K; ++ky) {
              const int sy = source_index(yy + ky - p, c.H, c.pad);
              if (sy < 0) continue;
              for (int kx = 0; kx < c.K; ++kx) {
                const int sx = source_index(xx + kx - p, c.W, c.pad);
                if (sx < 0) continue;
                s += w[((size_t(co) * c.Cin + ci) * c.K + ky) * c.K + kx] *
                     x[((size_t(n) * c.Cin + ci) * c.H + sy) * c.W + sx];
              }
            }
          y[((size_t(n) * c.Cout + co) * c.H + yy) * c.W + xx] = s;
        }
  return y;
}

struct Data {
  std::vector<float> x, w, b, dy;
};

Data make_data(const Case& c, uint64_t seed, float xs = 1.0f, float ws = 1.0f, float gs = 1.0f) {
  Data d;
  d.x = testing::random_normal(size_t(c.N) * c.Cin * c.H * c.W, seed, xs);
  d.w = testing::random_normal(size_t(c.Cout) * c.Cin * c.K * c.K, seed + 1, ws);
  d.b = testing::random_normal(size_t(c.Cout), seed + 2, ws);
  d.dy = testing::random_normal(size_t(c.N) * c.Cout * c.H * c.W, seed + 3, gs);
  return d;
}

nn::Conv2dGrads run_backward(const Case& c, const Data& d, bool need_dx = true, bool need_params = true) {
  Tensor x = Tensor::from_host(d.x, {c.N, c.Cin, c.H, c.W});
  Tensor w = Tensor::from_host(d.w, {c.Cout, c.Cin, c.K, c.K});
  Tensor dy = Tensor::from_host(d.dy, {c.N, c.Cout, c.H, c.W});
  return nn::conv2d_backward(x, w, dy, c.pad, need_dx, need_params, g_algo);
}

std::vector<float> run_forward(const Case& c, const Data& d) {
  Tensor x = Tensor::from_host(d.x, {c.N, c.Cin, c.H, c.W});
  Tensor w = Tensor::from_host(d.w, {c.Cout, c.Cin, c.K, c.K});
  Tensor b = c.bias ? Tensor::from_host(d.b, {c.Cout}) : Tensor();
  return nn::conv2d_forward(x, w, b, c.pad, g_algo).to_host();
}

// Forward check. Tolerance: float accumulation over Cin*k*k <= 144 unit-scale products gives errors of
// ~1e-6 relative to the sum of |terms|; rtol 1e-4 / atol 1e-4 (values are O(1..10)) leaves margin
// while a wrong tap (an O(1) error) fails.
void check_forward(const Case& c, uint64_t seed) {
  Data d = make_data(c, seed);
  auto want = ref_conv(c, to_double(d.x), to_double(d.w), to_double(d.b));
  check_close(run_forward(c, d), want, 1e-4, 1e-4, "conv2d_forward " + name(c));
}

// Backward check against central differences of L = <dy, conv(x, w, b)> in double. L is linear in each
// argument, so the differences are exact up to double rounding (h = 1e-2 keeps cancellation tiny).
// Tolerance rtol 1e-4, atol 1e-4 (float GEMM over <= N*H*W = 84 or Cout*k*k = 45 terms of O(1)).
// At most `probe` indices of x are probed (all when the tensor is small).
void check_backward(const Case& c, uint64_t seed, size_t probe = 400) {
  Data d = make_data(c, seed);
  const auto xd = to_double(d.x), wd = to_double(d.w), bd = to_double(d.b), gd = to_double(d.dy);
  auto g = run_backward(c, d);
  REQUIRE(g.dx.defined());
  REQUIRE(g.dw.defined());
  REQUIRE(g.db.defined());

  std::vector<size_t> xi;
  const size_t stride = std::max<size_t>(1, xd.size() / probe);
  for (size_t i = 0; i < xd.size(); i += stride) xi.push_back(i);
  auto fx = [&](const std::vector<double>& v) { return testing::dot(gd, ref_conv(c, v, wd, bd)); };
  auto want_dx = testing::finite_difference_at(fx, xd, xi, 1e-2);
  auto dx = g.dx.to_host();
  std::vector<float> got_dx;
  for (size_t i : xi) got_dx.push_back(dx[i]);
  check_close(got_dx, want_dx, 1e-4, 1e-4, "conv2d dx " + name(c));

  auto fw = [&](const std::vector<double>& v) { return testing::dot(gd, ref_conv(c, xd, v, bd)); };
  check_close(g.dw.to_host(), testing::finite_difference(fw, wd, 1e-2), 1e-4, 1e-4, "conv2d dw " + name(c));

  Case cb = c;
  cb.bias = true;
  auto fb = [&](const std::vector<double>& v) { return testing::dot(gd, ref_conv(cb, xd, wd, v)); };
  check_close(g.db.to_host(), testing::finite_difference(fb, bd, 1e-2), 1e-4, 1e-4, "conv2d db " + name(c));
}

// Sets STYLERF_CONV_SCRATCH_BYTES for the scope (forces the row-chunked path).
struct ScratchLimit {
  explicit ScratchLimit(size_t bytes) { setenv("STYLERF_CONV_SCRATCH_BYTES", std::to_string(bytes).c_str(), 1); }
  ~ScratchLimit() { unsetenv("STYLERF_CONV_SCRATCH_BYTES"); }
};


// Runs f once per algorithm with g_algo set.
template <class F>
void for_each_algo(F&& f) {
  for (nn::ConvAlgo a : kAlgos) {
    g_algo = a;
    CAPTURE(nn::conv_algo_name(a));
    f();
  }
  g_algo = nn::ConvAlgo::Im2col;
}

}  // namespace

TEST_CASE("conv2d forward matches the double reference (k=3 zero/reflect, k=1, bias or not)") {
  for_each_algo([&] {
    uint64_t seed = 10;
    for (int k : {3, 1})
      for (Padding pad : {Padding::Zero, Padding::Reflect})
        for (bool bias : {false, true}) check_forward({2, 3, 5, 7, 6, k, pad, bias}, seed++);
    // Wider rows exercise the 8-wide vector paths of im2col and bias_add; 16 channels a real GEMM size.
    check_forward({1, 2, 3, 5, 21, 3, Padding::Reflect, true}, 30);
    check_forward({1, 2, 3, 5, 21, 3, Padding::Zero, false}, 31);
    check_forward({1, 16, 8, 24, 32, 3, Padding::Reflect, true}, 32);
    // Rows wide enough that the Winograd tile kernels' 8-tile groups take their interior (unchecked) load
    // path for F(2x2) and F(4x4), then a partial last group; odd H leaves partial tile rows.
    check_forward({1, 2, 3, 5, 70, 3, Padding::Reflect, true}, 33);
    check_forward({2, 3, 2, 7, 75, 3, Padding::Zero, true}, 34);
  });
}

TEST_CASE("conv2d backward dx, dw, db match finite differences") {
  for_each_algo([&] {
    uint64_t seed = 100;
    for (int k : {3, 1})
      for (Padding pad : {Padding::Zero, Padding::Reflect}) check_backward({2, 3, 5, 7, 6, k, pad, false}, seed++);
    // 8-wide vector path of col2im, including the reflected columns inside a vector.
    check_backward({1, 2, 3, 4, 19, 3, Padding::Reflect, false}, 110);
    check_backward({1, 2, 3, 4, 19, 3, Padding::Zero, false}, 111);
    // Interior and partial 8-tile groups of the Winograd kernels (see the forward test).
    check_backward({1, 2, 3, 5, 70, 3, Padding::Reflect, false}, 112);
    check_backward({2, 2, 2, 7, 75, 3, Padding::Zero, false}, 113);
    // 11 input channels: a full and a partial 8-channel group of the Winograd filter kernels.
    check_backward({1, 11, 2, 5, 9, 3, Padding::Reflect, false}, 114);
  });
}

TEST_CASE("conv2d reflect edge cases: H, W = 2 and 3 (rows 1 and H-2 coincide)") {
  for_each_algo([&] {
    for (int s : {2, 3}) {
      Case c{1, 2, 2, s, s, 3, Padding::Reflect, true};
      check_forward(c, 200 + s);
      check_backward(c, 210 + s);
    }
    // 2 x 9: both row reflections hit every row, columns take the vector path.
    Case c{2, 2, 3, 2, 9, 3, Padding::Reflect, true};
    check_forward(c, 220);
    check_backward(c, 221);
  });
}

TEST_CASE("conv2d row-chunked path (scratch limit smaller than one image's col) matches") {
  // Cin*k*k = 27, W = 6: one col row takes 648 bytes; 1400 bytes gives 2-row chunks (4 chunks for
  // H = 7, the last one row). Then W = 11 (8-wide vector path of the accumulating col2im) with
  // Cin*k*k = 18: 792 bytes a row, 1-row chunks.
  {
    ScratchLimit limit(1400);
    for (Padding pad : {Padding::Zero, Padding::Reflect}) {
      Case c{2, 3, 5, 7, 6, 3, pad, true};
      check_forward(c, 300);
      check_backward(c, 301);
    }
    Case c{1, 2, 3, 7, 11, 3, Padding::Reflect, true};
    check_forward(c, 302);
    check_backward(c, 303);
  }
  // A limit below one row is a clear error.
  ScratchLimit tiny(100);
  Case c{1, 3, 5, 7, 6, 3, Padding::Zero, false};
  std::string e = error_of([&] { run_forward(c, make_data(c, 304)); });
  CHECK(e.find("scratch limit") != std::string::npos);
}

TEST_CASE("conv2d backward computes only what is asked for") {
  for_each_algo([&] {
    Case c{1, 2, 3, 4, 5, 3, Padding::Reflect, false};
    Data d = make_data(c, 400);
    auto only_dx = run_backward(c, d, true, false);
    CHECK(only_dx.dx.defined());
    CHECK(!only_dx.dw.defined());
    CHECK(!only_dx.db.defined());
    auto only_params = run_backward(c, d, false, true);
    CHECK(!only_params.dx.defined());
    CHECK(only_params.dw.defined());
    auto both = run_backward(c, d);
    // Same results whichever way they are requested (no dependence on leftover scratch content).
    CHECK(only_dx.dx.to_host() == both.dx.to_host());
    CHECK(only_params.dw.to_host() == both.dw.to_host());
  });
}

TEST_CASE("conv2d bias gradient is the sum of dy over images and pixels, across its two stages") {
  // db does not depend on x or w, so its reference is the double sum of dy. The shapes cut each channel
  // plane into 1, 2 (4096 pixels) and 3 uneven parts (65 x 70) of about 2048 pixels (lib/nn/columns.cpp).
  for (const Case c : {Case{3, 1, 5, 1, 1, 1, Padding::Zero, true}, Case{1, 1, 2, 64, 64, 1, Padding::Zero, true},
                       Case{2, 1, 3, 65, 70, 1, Padding::Zero, true}}) {
    CAPTURE(name(c));
    Data d = make_data(c, 450);
    nn::Conv2dGrads g = run_backward(c, d, false, true);
    REQUIRE(g.db.defined());
    const size_t hw = size_t(c.H) * c.W;
    std::vector<double> want(size_t(c.Cout), 0.0);
    for (int n = 0; n < c.N; ++n)
      for (int co = 0; co < c.Cout; ++co)
        for (size_t i = 0; i < hw; ++i) want[size_t(co)] += d.dy[(size_t(n) * c.Cout + co) * hw + i];
    // Sums of up to 9100 terms of O(1) (magnitude ~100): float blocks of 8 lanes err ~1e-5.
    check_close(g.db.to_host(), want, 1e-5, 1e-4, "conv2d db " + name(c));
  }
}

TEST_CASE("conv2d with huge and tiny magnitudes stays finite and accurate") {
  for_each_algo([&] {
    Case c{1, 3, 4, 5, 6, 3, Padding::Reflect, false};
    struct Scale {
      float x, w, g;
    };
    // Huge inputs with tiny weights (products O(1)), huge products (1e34 each, sums < FLT_MAX),
    // tiny inputs (1e-30, still normal floats), tiny weights (1e-25 against gradients of 1e-5: products
    // ~1e-30; the kernels flush what falls below 1e-38 to zero by design, host/runtime.cpp).
    for (Scale s : {Scale{1e15f, 1e-15f, 1e15f}, Scale{1e17f, 1e17f, 1.0f}, Scale{1e-30f, 1.0f, 1.0f},
                    Scale{1.0f, 1e-25f, 1e-5f}}) {
      CAPTURE(s.x);
      CAPTURE(s.w);
      Data d = make_data(c, 500, s.x, s.w, s.g);
      const auto xd = to_double(d.x), wd = to_double(d.w), gd = to_double(d.dy);
      auto want = ref_conv(c, xd, wd, {});
      const double ys = double(s.x) * s.w;
      // Relative accuracy as in the unit-scale test, with atol scaled to the output magnitude.
      check_close(run_forward(c, d), want, 1e-4, 1e-4 * ys, "conv2d_forward scaled");

      auto g = run_backward(c, d);
      auto fx = [&](const std::vector<double>& v) { return testing::dot(gd, ref_conv(c, v, wd, {})); };
      auto fw = [&](const std::vector<double>& v) { return testing::dot(gd, ref_conv(c, xd, v, {})); };
      std::vector<size_t> idx;
      for (size_t i = 0; i < xd.size(); i += 7) idx.push_back(i);
      auto want_dx = testing::finite_difference_at(fx, xd, idx, 1e-2 * s.x);
      auto dx = g.dx.to_host();
      std::vector<float> got_dx;
      for (size_t i : idx) got_dx.push_back(dx[i]);
      check_close(got_dx, want_dx, 1e-4, 1e-4 * double(s.w) * s.g, "conv2d dx scaled");
      check_close(g.dw.to_host(), testing::finite_difference(fw, wd, 1e-2 * s.w), 1e-4, 1e-4 * double(s.x) * s.g,
                  "conv2d dw scaled");
      CHECK(testing::all_finite(g.db.to_host()));
    }
  });
}

TEST_CASE("conv2d of a constant input: interior outputs equal the weight sum, no NaN") {
  for_each_algo([&] {
    // Reflect padding of a constant image is constant, so every output is sum(w) * value + b.
    Case c{1, 2, 3, 6, 10, 3, Padding::Reflect, true};
    Data d = make_data(c, 600);
    std::fill(d.x.begin(), d.x.end(), 2.0f);
    auto y = run_forward(c, d);
    for (int co = 0; co < c.Cout; ++co) {
      double s = d.b[co];
      for (int i = 0; i < c.Cin * 9; ++i) s += 2.0 * d.w[co * c.Cin * 9 + i];
      for (int p = 0; p < c.H * c.W; ++p) CHECK(y[co * c.H * c.W + p] == doctest::Approx(s).epsilon(1e-5));
    }
  });
}

TEST_CASE("conv2d bad shapes give clear errors") {
  Tensor x = Tensor::zeros({1, 3, 4, 4}), w = Tensor::zeros({5, 2, 3, 3});
  std::string e = error_of([&] { nn::conv2d_forward(x, w, Tensor(), Padding::Zero); });
  CHECK(e.find("channel mismatch") != std::string::npos);
  CHECK(e.find("[1, 3, 4, 4]") != std::string::npos);

  Tensor x1 = Tensor::zeros({1, 2, 1, 4}), w3 = Tensor::zeros({5, 2, 3, 3});
  e = error_of([&] { nn::conv2d_forward(x1, w3, Tensor(), Padding::Reflect); });
  CHECK(e.find("reflect padding needs H, W >= 2") != std::string::npos);
  e = error_of([&] { nn::conv2d_backward(x1, w3, Tensor::zeros({1, 5, 1, 4}), Padding::Reflect, true, true); });
  CHECK(e.find("reflect padding needs H, W >= 2") != std::string::npos);
  // Zero padding handles H = 1.
  CHECK(error_of([&] { nn::conv2d_forward(x1, w3, Tensor(), Padding::Zero); }).empty());

  Tensor w2 = Tensor::zeros({5, 2, 2, 2});
  e = error_of([&] { nn::conv2d_forward(Tensor::zeros({1, 2, 4, 4}), w2, Tensor(), Padding::Zero); });
  CHECK(e.find("1x1 or 3x3") != std::string::npos);

  e = error_of([&] { nn::conv2d_forward(Tensor::zeros({1, 2, 4, 4}), w3, Tensor::zeros({4}), Padding::Zero); });
  CHECK(e.find("bias") != std::string::npos);

  e = error_of([&] {
    nn::conv2d_backward(Tensor::zeros({1, 2, 4, 4}), w3, Tensor::zeros({1, 5, 4, 3}), Padding::Zero, true, true);
  });
  CHECK(e.find("dy") != std::string::npos);

  e = error_of([&] { nn::conv2d_forward(Tensor::zeros({2, 4, 4}), w3, Tensor(), Padding::Zero); });
  CHECK(e.find("[N,Cin,H,W]") != std::string::npos);
}

TEST_CASE("conv2d filter cache: the Winograd transform of the tensor it saw, reused, bit-identical to none") {
  const Case c{2, 12, 10, 9, 7, 3, Padding::Reflect, true};
  const Data d = make_data(c, 41);
  const Tensor x = Tensor::from_host(d.x, {c.N, c.Cin, c.H, c.W}), b = Tensor::from_host(d.b, {c.Cout});
  const Tensor dy = Tensor::from_host(d.dy, {c.N, c.Cout, c.H, c.W});
  const host::Shape ws{c.Cout, c.Cin, 3, 3};
  nn::ConvFilterCache cache;  // one cache for both algorithms: each keeps its own transform
  for (nn::ConvAlgo algo : {nn::ConvAlgo::Winograd2, nn::ConvAlgo::Winograd4}) {
    CAPTURE(nn::conv_algo_name(algo));
    Tensor w = Tensor::from_host(d.w, ws);
    const std::vector<float> plain = nn::conv2d_forward(x, w, b, c.pad, algo).to_host();
    CHECK(nn::conv2d_forward(x, w, b, c.pad, algo, &cache).to_host() == plain);  // made
    CHECK(nn::conv2d_forward(x, w, b, c.pad, algo, &cache).to_host() == plain);  // reused
    const std::vector<float> dx = nn::conv2d_backward(x, w, dy, c.pad, true, false, algo).dx.to_host();
    CHECK(nn::conv2d_backward(x, w, dy, c.pad, true, false, algo, &cache).dx.to_host() == dx);

    // Writing into the same buffer is invisible to the cache (the caller's contract: clear()). That the old
    // output comes back shows the transform really is reused.
    std::vector<float> w2 = d.w;
    for (float& v : w2) v = -0.5f * v + 0.01f;
    w.upload(w2);
    const std::vector<float> fresh = nn::conv2d_forward(x, w, b, c.pad, algo).to_host();
    REQUIRE(fresh != plain);
    CHECK(nn::conv2d_forward(x, w, b, c.pad, algo, &cache).to_host() == plain);
    cache.clear();
    CHECK(nn::conv2d_forward(x, w, b, c.pad, algo, &cache).to_host() == fresh);

    // A replaced tensor (what a load does) is noticed without clear().
    const Tensor w3 = Tensor::from_host(d.w, ws);
    CHECK(nn::conv2d_forward(x, w3, b, c.pad, algo, &cache).to_host() == plain);
  }
  // im2col and 1x1 convs ignore the cache.
  const Tensor w = Tensor::from_host(d.w, ws);
  CHECK(nn::conv2d_forward(x, w, b, c.pad, nn::ConvAlgo::Im2col, &cache).to_host() ==
        nn::conv2d_forward(x, w, b, c.pad, nn::ConvAlgo::Im2col).to_host());
}

TEST_CASE("conv algorithm names: parse, Auto's resolution, and a clear error for a bad name") {
  CHECK(nn::parse_conv_algo("winograd4") == nn::ConvAlgo::Winograd4);
  CHECK(error_of([] { nn::parse_conv_algo("fft"); }).find("unknown conv algorithm 'fft'") != std::string::npos);
  // An explicit choice is kept; one whose tiles exceed the limit falls back to im2col.
  CHECK(nn::resolve_conv_algo(nn::ConvAlgo::Winograd2, 8, 8, 16, 16) == nn::ConvAlgo::Winograd2);
  {
    ScratchLimit limit(1000);
    CHECK(nn::resolve_conv_algo(nn::ConvAlgo::Winograd4, 8, 8, 16, 16) == nn::ConvAlgo::Im2col);
  }
  setenv("STYLERF_CONV_ALGO", "im2col", 1);
  CHECK(nn::resolve_conv_algo(nn::ConvAlgo::Auto, 8, 8, 16, 16) == nn::ConvAlgo::Im2col);
  setenv("STYLERF_CONV_ALGO", "bogus", 1);
  CHECK(error_of([] { nn::resolve_conv_algo(nn::ConvAlgo::Auto, 8, 8, 16, 16); }).find("STYLERF_CONV_ALGO") !=
        std::string::npos);
  unsetenv("STYLERF_CONV_ALGO");
}
