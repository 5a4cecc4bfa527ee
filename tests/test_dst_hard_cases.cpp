// DST's hard cases (lib/style/dst.hpp, kernels/dst.cl), each against an exact value or the double reference
// of tests/style_reference.hpp:
//  - a style with exactly constant channels (std exactly 0), dead (all-zero) channels, as ReLU features have,
//    and a rank-deficient covariance: exact means and stds, the styled channel exactly w_r * mean, the std's
//    gradient there exactly 0 (kernels/dst.cl's subgradient; the central differences of sqrt(var) at var = 0
//    are 0 too), and the whole backward against central differences of the reference;
//  - the backward through a near-constant channel (d std / d s changes as 1/std) and through large features;
//  - scale: a power of two scales the mean exactly and the std to rounding while nothing overflows; near 1e-20
//    the squared deviations fall below FLT_MIN and flush (std exactly 0); from ~1e14 the output, from ~1e18
//    the statistics overflow float: errors naming DST;
//  - NaN / Inf in the style or content features, and fewer than 2 style positions: errors naming DST.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "host/tensor.hpp"
#include "lib/style/dst.hpp"
#include "tests/style_reference.hpp"
#include "tests/style_reference_params.hpp"
#include "tests/directional_derivative.hpp"
#include "tests/testing.hpp"

using namespace stylerf;
using host::Tensor;
using testing::check_close;
using testing::to_double;
namespace ref = testing::style_ref;

namespace {

constexpr int C = 256, E = 32;

using Loss = std::function<double(const std::vector<double>&)>;

// Our gradient against central differences (step h) of loss(x): at the entries idx, and along 3 random
// directions over the whole tensor.
void fd_check(const std::string& what, const std::vector<float>& ours, const std::vector<double>& x, const Loss& loss,
              const std::vector<size_t>& idx, double h, double rtol = 3e-3) {
  REQUIRE(ours.size() == x.size());
  const std::vector<double> fd = testing::finite_difference_at(loss, x, idx, h);
  std::vector<float> got;
  double scale = 0;
  for (size_t k = 0; k < idx.size(); ++k) {
    got.push_back(ours[idx[k]]);
    scale = std::max(scale, std::abs(fd[k]));
  }
  for (float g : ours) scale = std::max(scale, double(std::abs(g)) * 1e-3);
  check_close(got, fd, rtol, 1e-3 * scale + 1e-12, what);
  testing::check_random_directions(what, ours, x, loss, h, rtol, 1e-12, 700);
}

// `count` entries spread over a tensor of n.
std::vector<size_t> spread(size_t n, int count) {
  std::vector<size_t> out;
  for (int i = 0; i < count; ++i) out.push_back(size_t((uint64_t(i) * 2654435761u + 11) % n));
  return out;
}

// Those of a [rows, cols] tensor, plus the entries of `channels` in its first and last rows.
std::vector<size_t> entries(int rows, int cols, const std::vector<int>& channels, int count) {
  std::vector<size_t> out = spread(size_t(rows) * cols, count);
  for (int r : {0, rows - 1})
    for (int j : channels) out.push_back(size_t(r) * cols + size_t(j));
  return out;
}

double max_abs(const std::vector<double>& v) {
  double m = 0;
  for (double x : v) m = std::max(m, std::abs(x));
  return m;
}

}  // namespace

TEST_CASE("constant and dead channels: std exactly 0, output exactly w_r * mean, no std gradient there") {
  const int L = 32, R = 8, distinct = 8;
  // 8 distinct rows, each 4 times: the covariance E^T E / L has rank <= 8 of 32.
  const auto rows = testing::random_normal(size_t(distinct) * C, 100, 1.0f, 0.5f);
  std::vector<float> s(size_t(L) * C);
  for (int l = 0; l < L; ++l) std::copy_n(rows.begin() + size_t(l % distinct) * C, C, s.begin() + size_t(l) * C);
  // 0.75 sums exactly over 32 rows and 1/32 is exact: the mean is exactly 0.75 and every deviation exactly 0.
  const std::vector<int> constant = {3, 100, 201}, dead = {0, 17, 64, 128, 255};
  std::vector<int> zero_std = constant;
  zero_std.insert(zero_std.end(), dead.begin(), dead.end());
  for (int l = 0; l < L; ++l) {
    for (int j : constant) s[size_t(l) * C + j] = 0.75f;
    for (int j : dead) s[size_t(l) * C + j] = 0.0f;
  }
  style::Dst d = style::Dst::create(true, 0, 101);
  style::Dst::StyleContext sctx;
  style::Dst::ApplyContext actx;
  const style::StyleCode code = d.style_code(Tensor::from_host(s, {L, C}), &sctx);
  const auto mean = code.mean.to_host(), sd = code.std.to_host();
  for (int j : constant) {
    CHECK(mean[size_t(j)] == 0.75f);
    CHECK(sd[size_t(j)] == 0.0f);
  }
  for (int j : dead) {
    CHECK(mean[size_t(j)] == 0.0f);
    CHECK(sd[size_t(j)] == 0.0f);
  }
  const ref::DstParams p = testing::dst_ref_params(d);
  const ref::Code rc = ref::style_code(to_double(s), L, p);
  check_close(mean, rc.mean, 1e-5, 1e-6, "mean");
  check_close(sd, rc.std, 1e-4, 1e-6, "std");
  check_close(code.T.to_host(), rc.T, 1e-4, 1e-6 * max_abs(rc.T), "T of a rank-deficient covariance");

  const auto c = testing::random_normal(size_t(R) * E, 102);
  auto acc = testing::random_uniform(R, 103, 0.2f, 1.0f);
  acc[1] = 0.0f;
  const auto y = d.apply(Tensor::from_host(c, {R, E}), Tensor::from_host(acc, {R}), code, &actx).to_host();
  // T c meets a column of W' = M diag(std) that is exactly 0: what is left is the bias, one rounded product.
  for (int r = 0; r < R; ++r) {
    for (int j : constant) CHECK(y[size_t(r) * C + j] == acc[size_t(r)] * 0.75f);
    for (int j : dead) CHECK(y[size_t(r) * C + j] == 0.0f);
  }
  const auto want_y = ref::dst_apply(to_double(c), to_double(acc), R, rc, p.unzip, true);
  check_close(y, want_y, 1e-4, 1e-6 * max_abs(want_y), "styled map");

  // The statistics' backward alone (no T gradient): ds = dmean / L + dstd (s - mean) / ((L - 1) std), and in a
  // zero-std channel exactly dmean / L (1/32: exact) — the dstd term is the subgradient 0, not 0/0.
  const auto dmean = testing::random_normal(C, 104), dstd = testing::random_normal(C, 105);
  d.zero_grad();
  const auto ds_stats = d.style_code_backward(sctx, Tensor(), Tensor::from_host(dmean, {C}),
                                              Tensor::from_host(dstd, {C}), true).to_host();
  std::vector<double> want_stats(size_t(L) * C);
  for (int l = 0; l < L; ++l)
    for (int j = 0; j < C; ++j) {
      const size_t i = size_t(l) * C + j;
      want_stats[i] = double(dmean[size_t(j)]) / L;
      if (rc.std[size_t(j)] > 0) want_stats[i] += dstd[size_t(j)] * (s[i] - rc.mean[size_t(j)]) / ((L - 1) * rc.std[size_t(j)]);
    }
  int not_exact = 0;
  for (int l = 0; l < L; ++l)
    for (int j : zero_std) not_exact += ds_stats[size_t(l) * C + j] != dmean[size_t(j)] / float(L);
  CHECK_MESSAGE(not_exact == 0, not_exact << " entries of zero-std channels are not exactly dmean / L");
  check_close(ds_stats, want_stats, 1e-4, 1e-6, "statistics backward");

  // The whole backward. The std gradients of the zero-std channels are not 0, so the guard is exercised.
  const auto g = testing::random_normal(size_t(R) * C, 106);
  d.zero_grad();
  const style::Dst::ApplyGrads ag = d.apply_backward(actx, Tensor::from_host(g, {R, C}), true);
  const auto dstd_full = ag.dstd.to_host();
  for (int j : constant) CHECK(dstd_full[size_t(j)] != 0.0f);
  const Tensor ds = d.style_code_backward(sctx, ag.dT, ag.dmean, ag.dstd, true);
  // unzip's gradient in a zero-std column is exactly 0 (its output there does not depend on it).
  const auto du = d.unzip_w.grad.to_host();
  for (int a = 0; a < E; ++a)
    for (int j : zero_std) CHECK(du[size_t(a) * C + j] == 0.0f);
  const auto sdd = to_double(s), cd = to_double(c), ad = to_double(acc), gd = to_double(g);
  fd_check("ds with zero-std channels", ds.to_host(), sdd, [&](const std::vector<double>& v) {
    return testing::dot(ref::dst_apply(cd, ad, R, ref::style_code(v, L, p), p.unzip, true), gd);
  }, entries(L, C, zero_std, 12), 1e-4);
  fd_check("dunzip with zero-std channels", du, p.unzip, [&](const std::vector<double>& v) {
    return testing::dot(ref::dst_apply(cd, ad, R, rc, v, true), gd);  // the style code does not depend on unzip
  }, entries(E, C, {3, 100, 0, 17}, 10), 1e-4);
}

TEST_CASE("the backward through a near-constant channel and through large features matches central differences") {
  const int L = 32, R = 6;
  const std::vector<int> watched = {5, 77, 190};
  struct Variant {
    const char* name;
    float scale, flat_deviation;  // flat_deviation > 0: the watched channels are 4 + flat_deviation * N(0, 1)
    double h;
  };
  // Near-constant: std ~1e-3 of a mean of 4, where the second derivative of the std (~1/std) would swamp a
  // step of 1e-4, so h = 1e-6. Large: features of ~1e3 (VGG's largest relu3_1 values), y ~ scale^3.
  for (const Variant v : {Variant{"near-constant channels", 1.0f, 1e-3f, 1e-6}, Variant{"features x 1024", 1024.0f, 0.0f, 0.1}}) {
    INFO(v.name);
    auto s = testing::random_normal(size_t(L) * C, 200, 1.0f, 0.5f);
    const auto noise = testing::random_normal(size_t(L) * C, 201);
    for (int l = 0; l < L; ++l)
      for (int j = 0; j < C; ++j) {
        float& x = s[size_t(l) * C + j];
        if (v.flat_deviation > 0 && std::find(watched.begin(), watched.end(), j) != watched.end())
          x = 4.0f + v.flat_deviation * noise[size_t(l) * C + j];
        x *= v.scale;
      }
    const auto c = testing::random_normal(size_t(R) * E, 202);
    const auto acc = testing::random_uniform(R, 203, 0.1f, 1.0f);
    const auto g = testing::random_normal(size_t(R) * C, 204);
    style::Dst d = style::Dst::create(true, 0, 205);
    style::Dst::StyleContext sctx;
    style::Dst::ApplyContext actx;
    const style::StyleCode code = d.style_code(Tensor::from_host(s, {L, C}), &sctx);
    const ref::DstParams p = testing::dst_ref_params(d);
    const auto sdd = to_double(s), cd = to_double(c), ad = to_double(acc), gd = to_double(g);
    const ref::Code rc = ref::style_code(sdd, L, p);
    if (v.flat_deviation > 0)
      for (int j : watched) CHECK(rc.std[size_t(j)] < 2e-3);
    check_close(code.std.to_host(), rc.std, 1e-3, 0.0, "std");
    const auto y = d.apply(Tensor::from_host(c, {R, E}), Tensor::from_host(acc, {R}), code, &actx).to_host();
    const auto want_y = ref::dst_apply(cd, ad, R, rc, p.unzip, true);
    check_close(y, want_y, 1e-4, 1e-5 * max_abs(want_y), "styled map");
    d.zero_grad();
    const style::Dst::ApplyGrads ag = d.apply_backward(actx, Tensor::from_host(g, {R, C}), true);
    const Tensor ds = d.style_code_backward(sctx, ag.dT, ag.dmean, ag.dstd, true);
    fd_check(std::string("ds, ") + v.name, ds.to_host(), sdd, [&](const std::vector<double>& x) {
      return testing::dot(ref::dst_apply(cd, ad, R, ref::style_code(x, L, p), p.unzip, true), gd);
    }, entries(L, C, watched, 12), v.h);
    fd_check(std::string("dc, ") + v.name, ag.dc.to_host(), cd, [&](const std::vector<double>& x) {
      return testing::dot(ref::dst_apply(x, ad, R, rc, p.unzip, true), gd);
    }, spread(cd.size(), 12), 1e-4);
  }
}

TEST_CASE("scaled features: exact where float holds them, std flushed to 0 below ~1e-19, overflow is an error") {
  const int L = 64, R = 8;
  auto base = testing::random_normal(size_t(L) * C, 300, 1.0f, 0.5f);
  for (float& x : base) x = std::clamp(x, -3.0f, 3.0f);  // every |deviation| < 6: below 8 = 2^-63 / 2^-66
  const auto c = testing::random_normal(size_t(R) * E, 301);
  const auto acc = testing::random_uniform(R, 302, 0.2f, 1.0f);
  style::Dst d = style::Dst::create(true, 0, 303);
  const ref::DstParams p = testing::dst_ref_params(d);
  const style::StyleCode unit = d.style_code(Tensor::from_host(base, {L, C}), nullptr);
  const auto mean1 = unit.mean.to_host(), std1 = unit.std.to_host();
  auto scaled = [&](int e) {
    std::vector<float> s = base;
    for (float& x : s) x = std::ldexp(x, e);
    return s;
  };
  auto apply = [&](const style::StyleCode& code) {
    return d.apply(Tensor::from_host(c, {R, E}), Tensor::from_host(acc, {R}), code, nullptr);
  };

  // 2^-40 and 2^30 (~1e-12 and ~1e9): the mean scales exactly, the std to OpenCL's sqrt (3 ulp); T (nearly the
  // bias-driven T of 0 at the small end, ~1e15 at the large) and the map follow the reference.
  for (int e : {-40, 30}) {
    CAPTURE(e);
    const auto s = scaled(e);
    const style::StyleCode code = d.style_code(Tensor::from_host(s, {L, C}), nullptr);
    const auto mean = code.mean.to_host(), sd = code.std.to_host();
    int mean_off = 0, std_off = 0;
    for (int j = 0; j < C; ++j) {
      mean_off += mean[size_t(j)] != std::ldexp(mean1[size_t(j)], e);
      std_off += !(std::abs(sd[size_t(j)] - std::ldexp(std1[size_t(j)], e)) <= 4e-7 * std::ldexp(std1[size_t(j)], e));
    }
    CHECK(mean_off == 0);
    CHECK(std_off == 0);
    const ref::Code rc = ref::style_code(to_double(s), L, p);
    check_close(code.T.to_host(), rc.T, 1e-4, 1e-6 * max_abs(rc.T), "T");
    const auto want_y = ref::dst_apply(to_double(c), to_double(acc), R, rc, p.unzip, true);
    check_close(apply(code).to_host(), want_y, 1e-4, 1e-6 * max_abs(want_y), "styled map");
  }

  // 2^-66 (~1.4e-20): the mean is still exact, but the squared deviations (< 2^-126) flush to 0, so std is
  // exactly 0 (docs/design.md's contract: 0 below FLT_MIN) and the map is exactly the flat-style w_r * mean.
  {
    const style::StyleCode code = d.style_code(Tensor::from_host(scaled(-66), {L, C}), nullptr);
    const auto mean = code.mean.to_host(), sd = code.std.to_host();
    int mean_off = 0, std_nonzero = 0;
    for (int j = 0; j < C; ++j) {
      mean_off += mean[size_t(j)] != std::ldexp(mean1[size_t(j)], -66);
      std_nonzero += sd[size_t(j)] != 0.0f;
    }
    CHECK(mean_off == 0);
    CHECK(std_nonzero == 0);
    const auto y = apply(code).to_host();
    int off = 0;
    for (int r = 0; r < R; ++r)
      for (int j = 0; j < C; ++j) off += y[size_t(r) * C + j] != acc[size_t(r)] * mean[size_t(j)];
    CHECK_MESSAGE(off == 0, off << " entries of the map are not exactly w_r * mean");
    const ref::Code rc = ref::style_code(to_double(scaled(-66)), L, p);
    check_close(code.T.to_host(), rc.T, 1e-4, 1e-6 * max_abs(rc.T), "T at 2^-66");
  }

  // 2^48 (~2.8e14): the statistics and T (~1e26) are finite, the map (~ scale^3) is not: apply refuses.
  {
    const style::StyleCode code = d.style_code(Tensor::from_host(scaled(48), {L, C}), nullptr);
    CHECK(testing::all_finite(code.T.to_host()));
    testing::expect_error([&] { apply(code); }, "dst apply: the styled features overflow float");
  }
  // 2^66 (~7.4e19): the squared deviations and the covariance overflow: style_code refuses.
  testing::expect_error([&] { d.style_code(Tensor::from_host(scaled(66), {L, C}), nullptr); },
                        "dst style_code: the style's statistics overflow float");
}

TEST_CASE("NaN or Inf features and styles of fewer than 2 positions are refused, naming DST and the cause") {
  const int L = 16, R = 4;
  const auto s = testing::random_normal(size_t(L) * C, 400, 1.0f, 0.5f);
  const auto c = testing::random_normal(size_t(R) * E, 401);
  const std::vector<float> acc = {0.5f, 1.0f, 0.0f, 0.25f};
  for (bool bias : {true, false}) {
    CAPTURE(bias);
    style::Dst d = style::Dst::create(bias, 0, 402);
    for (float bad : {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity(),
                      -std::numeric_limits<float>::infinity()}) {
      CAPTURE(bad);
      std::vector<float> sb = s;
      sb[size_t(5) * C + 9] = bad;
      testing::expect_error([&] { d.style_code(Tensor::from_host(sb, {L, C}), nullptr); },
                            "dst style_code: the style features hold a NaN or an infinity");
      const style::StyleCode code = d.style_code(Tensor::from_host(s, {L, C}), nullptr);
      std::vector<float> cb = c;
      cb[size_t(2) * E + 31] = bad;
      testing::expect_error([&] { d.apply(Tensor::from_host(cb, {R, E}), Tensor::from_host(acc, {R}), code, nullptr); },
                            "dst apply: the content features c (or the opacities acc) hold a NaN or an infinity");
      if (bias) {  // acc only enters through the bias
        std::vector<float> ab = acc;
        ab[3] = bad;
        testing::expect_error([&] { d.apply(Tensor::from_host(c, {R, E}), Tensor::from_host(ab, {R}), code, nullptr); },
                              "dst apply: the content features c (or the opacities acc) hold a NaN or an infinity");
      }
    }
    // One position (or none) has no unbiased std.
    for (int rows : {1, 0}) {
      CAPTURE(rows);
      testing::expect_error(
          [&] {
            d.style_code(Tensor::from_host(std::vector<float>(s.begin(), s.begin() + size_t(rows) * C), {rows, C}),
                         nullptr);
          },
          "dst style_code: a style needs at least 2 feature positions");
    }
  }
}
