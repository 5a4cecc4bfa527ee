// SICT on the feature field's components (Sict::forward_factored, lib/style/sict_factored.cpp): x = comps B is
// never formed, yet the output, the weight and bias gradients and the statistics must be SICT's on x:
//  - forward against the double reference of tests/style_reference.hpp applied to x = comps B (in double),
//    in every mode, training and evaluation;
//  - dW and db against central differences of that reference, and against the unfactored op's backward;
//  - the statistics handed to update_running equal x's batch mean and biased variance;
//  - hard cases: constant components (std -> 0), components far from zero (mean 1e3, spread 1), a batch
//    of one point, a rank-deficient basis, sampling invariance in evaluation, and bad input.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "host/tensor.hpp"
#include "lib/style/sict.hpp"
#include "tests/sict_testing.hpp"
#include "tests/style_reference.hpp"
#include "tests/testing.hpp"

using namespace stylerf;
using host::Tensor;
using testing::check_close;
using testing::ref_mode;
using testing::to_double;
namespace ref = testing::style_ref;

namespace {

constexpr int C = 256, E = 32;

// x = comps B in double.
std::vector<double> features(const std::vector<float>& comps, const std::vector<float>& basis, int K, int F) {
  return ref::linear(to_double(comps), to_double(basis), {}, K, F, C);
}

struct Case {
  style::SictMode mode;
  bool training;
  std::string name() const { return std::string(style::sict_mode_name(mode)) + (training ? " training" : " evaluation"); }
};

const Case kCases[] = {{style::SictMode::VolumeAdaptive, true},
                       {style::SictMode::VolumeAdaptive, false},
                       {style::SictMode::VanillaIn, false},
                       {style::SictMode::None, true}};

style::Sict make_sict(style::SictMode mode, uint64_t seed) {
  style::Sict s = style::Sict::create(mode, 0, seed);
  s.running_mean.value = Tensor::from_host(testing::random_normal(C, seed + 1, 0.3f), {C});
  s.running_var.value = Tensor::from_host(testing::random_uniform(C, seed + 2, 0.5f, 2.0f), {C});
  return s;
}

std::vector<double> reference(const style::Sict& s, const std::vector<double>& x, int K, bool training) {
  return ref::sict(x, K, to_double(s.qkv_w.value.to_host()), to_double(s.qkv_b.value.to_host()), ref_mode(s.mode),
                   training, to_double(s.running_mean.value.to_host()), to_double(s.running_var.value.to_host()));
}

}  // namespace

TEST_CASE("factored SICT forward matches the double reference on x = comps B, in every mode") {
  const int K = 37, F = 40;
  const auto comps = testing::random_normal(size_t(K) * F, 1, 0.8f, 0.2f);
  const auto basis = testing::random_normal(size_t(F) * C, 2, 0.3f);
  const auto x = features(comps, basis, K, F);
  for (const Case& c : kCases) {
    CAPTURE(c.name());
    style::Sict s = make_sict(c.mode, 10);
    style::Sict::Context ctx;
    const Tensor y = s.forward_factored(Tensor::from_host(comps, {K, F}), Tensor::from_host(basis, {F, C}), c.training, &ctx);
    check_close(y.to_host(), reference(s, x, K, c.training), 1e-4, 1e-5, "factored sict " + c.name());
    CHECK(ctx.factored());
    CHECK(!ctx.x.defined());
    CHECK(!ctx.normed.defined());
    if (ctx.batch_stats) {  // what update_running reads: x's batch mean and biased variance
      std::vector<double> mean, var;
      ref::column_mean_var(x, K, C, 0, mean, var);
      check_close(ctx.mean.to_host(), mean, 1e-5, 1e-6, "batch mean of x");
      check_close(ctx.var.to_host(), var, 1e-4, 1e-6, "batch variance of x");
    }
  }
}

TEST_CASE("factored SICT dW and db match central differences and the unfactored backward") {
  const int K = 23, F = 24;
  const auto comps = testing::random_normal(size_t(K) * F, 3, 1.0f, 0.4f);
  const auto basis = testing::random_normal(size_t(F) * C, 4, 0.25f);
  const auto g = testing::random_normal(size_t(K) * E, 5);
  const auto x = features(comps, basis, K, F);
  std::vector<float> xf(x.begin(), x.end());
  for (const Case& c : kCases) {
    CAPTURE(c.name());
    style::Sict s = make_sict(c.mode, 20);
    style::Sict::Context ctx;
    s.forward_factored(Tensor::from_host(comps, {K, F}), Tensor::from_host(basis, {F, C}), c.training, &ctx);
    s.zero_grad();
    CHECK(!s.backward(ctx, Tensor::from_host(g, {K, E}), false).defined());
    const auto dw = s.qkv_w.grad.to_host(), db = s.qkv_b.grad.to_host();
    const auto w = to_double(s.qkv_w.value.to_host()), b = to_double(s.qkv_b.value.to_host());
    const auto rm = to_double(s.running_mean.value.to_host()), rv = to_double(s.running_var.value.to_host());
    const ref::Mode m = ref_mode(c.mode);
    // Central differences of <g, sict(x)> at every weight of a few q/k/v columns and at every bias.
    std::vector<size_t> idx;
    for (int i = 0; i < C; i += 17) idx.push_back(size_t(i) * 3 * E + size_t(i % (3 * E)));
    const auto fd_w = testing::finite_difference_at(
        [&](const std::vector<double>& v) { return testing::dot(ref::sict(x, K, v, b, m, c.training, rm, rv), to_double(g)); },
        w, idx, 1e-4);
    std::vector<float> got;
    for (size_t i : idx) got.push_back(dw[i]);
    check_close(got, fd_w, 3e-3, 1e-4, "factored dW " + c.name());
    const auto fd_b = testing::finite_difference(
        [&](const std::vector<double>& v) { return testing::dot(ref::sict(x, K, w, v, m, c.training, rm, rv), to_double(g)); },
        b, 1e-4);
    check_close(db, fd_b, 3e-3, 1e-4, "factored db " + c.name());
    // The unfactored op on the same x (in float) gives the same gradients, up to float rounding.
    style::Sict plain = make_sict(c.mode, 20);
    style::Sict::Context pctx;
    plain.forward(Tensor::from_host(xf, {K, C}), c.training, &pctx);
    plain.zero_grad();
    plain.backward(pctx, Tensor::from_host(g, {K, E}), false);
    check_close(dw, to_double(plain.qkv_w.grad.to_host()), 1e-3, 1e-5, "factored vs plain dW " + c.name());
    check_close(db, to_double(plain.qkv_b.grad.to_host()), 1e-3, 1e-5, "factored vs plain db " + c.name());
  }
}

TEST_CASE("factored SICT: constant components, a batch of one, and a rank-deficient basis stay finite and exact") {
  const int K = 16, F = 12;
  const auto row = testing::random_normal(F, 30, 2.0f);
  std::vector<float> comps;
  for (int r = 0; r < K; ++r) comps.insert(comps.end(), row.begin(), row.end());
  auto basis = testing::random_normal(size_t(F) * C, 31, 0.5f);
  for (int c = 0; c < C; ++c) basis[size_t(F - 1) * C + c] = basis[size_t(F - 2) * C + c];  // two equal rows
  const auto x = features(comps, basis, K, F);
  for (int rows : {K, 1}) {
    CAPTURE(rows);
    style::Sict s = make_sict(style::SictMode::VolumeAdaptive, 32);
    style::Sict::Context ctx;
    const std::vector<float> part(comps.begin(), comps.begin() + size_t(rows) * F);
    const Tensor y = s.forward_factored(Tensor::from_host(part, {rows, F}), Tensor::from_host(basis, {F, C}), true, &ctx);
    // Every point normalises to 0: each output is the attention of the bias alone.
    const std::vector<double> xr(x.begin(), x.begin() + size_t(rows) * C);
    check_close(y.to_host(), reference(s, xr, rows, true), 1e-4, 1e-5, "constant components");
    s.zero_grad();
    s.backward(ctx, Tensor::from_host(testing::random_normal(size_t(rows) * E, 33), {rows, E}), false);
    CHECK(testing::all_finite(s.qkv_w.grad.to_host()));
    CHECK(testing::all_finite(s.qkv_b.grad.to_host()));
    s.update_running(ctx);
    CHECK(testing::all_finite(s.running_var.value.to_host()));
  }
}

TEST_CASE("factored SICT: components far from zero (mean 1e3, spread 1) lose no more than the unfactored op") {
  // Centring the components first keeps the cancellation where the plain op has it (x - mean per
  // element); a covariance from E[f f^T] - mean mean^T would lose all digits here.
  const int K = 64, F = 16;
  const auto comps = testing::random_normal(size_t(K) * F, 40, 1.0f, 1000.0f);
  const auto basis = testing::random_normal(size_t(F) * C, 41, 0.25f);
  const auto x = features(comps, basis, K, F);
  std::vector<float> xf(x.begin(), x.end());
  style::Sict s = make_sict(style::SictMode::VolumeAdaptive, 42);
  const auto want = reference(s, x, K, true);
  const auto got = s.forward_factored(Tensor::from_host(comps, {K, F}), Tensor::from_host(basis, {F, C}), true, nullptr);
  const auto plain = s.forward(Tensor::from_host(xf, {K, C}), true, nullptr);
  double err = 0, plain_err = 0;
  const auto g = got.to_host(), p = plain.to_host();
  for (size_t i = 0; i < want.size(); ++i) {
    err = testing::max_or_nan(err, std::abs(double(g[i]) - want[i]));
    plain_err = testing::max_or_nan(plain_err, std::abs(double(p[i]) - want[i]));
  }
  MESSAGE("max error: factored " << err << ", plain " << plain_err);
  CHECK(err <= std::max(4 * plain_err, 1e-4));
}

TEST_CASE("factored SICT in evaluation: a point's output does not depend on the other points") {
  const int K = 30, F = 20;
  const auto comps = testing::random_normal(size_t(K) * F, 50, 1.0f, 0.3f);
  const auto basis = testing::random_normal(size_t(F) * C, 51, 0.3f);
  style::Sict s = make_sict(style::SictMode::VolumeAdaptive, 52);
  const Tensor B = Tensor::from_host(basis, {F, C});
  const auto all = s.forward_factored(Tensor::from_host(comps, {K, F}), B, false, nullptr).to_host();
  const std::vector<float> one(comps.begin() + size_t(7) * F, comps.begin() + size_t(8) * F);
  const auto alone = s.forward_factored(Tensor::from_host(one, {1, F}), B, false, nullptr).to_host();
  for (int i = 0; i < E; ++i) CHECK(alone[size_t(i)] == doctest::Approx(all[size_t(7) * E + i]).epsilon(1e-5));
}

TEST_CASE("factored SICT refuses bad input and a dx it cannot give") {
  style::Sict s = make_sict(style::SictMode::VolumeAdaptive, 60);
  const Tensor comps = Tensor::full({5, 8}, 0.5f);
  testing::expect_error([&] { s.forward_factored(comps, Tensor::full({9, C}, 0.1f), true, nullptr); }, "basis");
  testing::expect_error([&] { s.forward_factored(Tensor(), Tensor::full({8, C}, 0.1f), true, nullptr); }, "components");
  style::Sict::Context ctx;
  s.forward_factored(comps, Tensor::full({8, C}, 0.1f), true, &ctx);
  testing::expect_error([&] { s.backward(ctx, Tensor::full({5, E}, 0.1f), true); }, "no dx");
}
