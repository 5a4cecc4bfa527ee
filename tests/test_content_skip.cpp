// The content skip (lib/style/content_skip.hpp): y += (Z B - acc mean) diag(g std / sqrt(var + eps)).
//  - forward against a double reference, Z read at a column offset of a wider matrix (as the style model
//    carries it beside SICT's columns), on a random basis and on the identity; no basis (2D maps: Z is the
//    features) gives the identity's output and gradients;
//  - backward: the gain's and the style std's gradients against central differences of <G, y> (linear in
//    each, so the differences are exact up to rounding);
//  - linear in (Z, acc): the skip of a ray's composited samples equals the composite of each sample's skip
//    (what lets it run after compositing, like DST), and a ray's output depends on its own row only;
//  - hard cases: a channel of zero variance (features exactly at their mean: exactly 0 added, however large
//    1/sqrt(eps) is), a style channel of std 0 (exactly 0 added), rays that kept nothing (Z = 0, acc = 0:
//    exactly 0), and huge features (finite, to the reference);
//  - bad shapes and a NaN among the features give errors naming the content skip.
#include <doctest/doctest.h>

#include <cmath>
#include <vector>

#include "host/tensor.hpp"
#include "lib/style/content_skip.hpp"
#include "tests/testing.hpp"

using namespace stylerf;
using host::Tensor;
using testing::check_close;
using testing::to_double;

namespace {

constexpr int C = 256;
constexpr double kEps = 1e-5;  // SICT's, written out

struct Case {
  int R, F, ld, col;
  std::vector<float> z, acc, basis, mean, var, std, gain;
};

Case random_case(int R, int F, int col, uint64_t seed, bool identity = false) {
  // The identity's Z is the whole features matrix (2D maps); a basis's sits in a wider one.
  Case c{R, F, identity ? F : col + F + 3, col, {}, {}, {}, {}, {}, {}, {}};
  c.z = testing::random_normal(size_t(R) * c.ld, seed, 1.0f);
  c.acc = testing::random_uniform(size_t(R), seed + 1, 0.0f, 1.0f);
  if (identity) {
    c.basis.assign(size_t(F) * C, 0.0f);
    for (int i = 0; i < F; ++i) c.basis[size_t(i) * C + i] = 1.0f;
  } else {
    c.basis = testing::random_normal(size_t(F) * C, seed + 2, 0.3f);
  }
  c.mean = testing::random_normal(C, seed + 3, 0.5f);
  c.var = testing::random_uniform(C, seed + 4, 0.05f, 3.0f);
  c.std = testing::random_uniform(C, seed + 5, 0.1f, 2.0f);
  c.gain = testing::random_uniform(C, seed + 6, 0.5f, 1.5f);
  return c;
}

// The double reference: y [R, 256] = (Z B - acc mean) diag(g std / sqrt(var + eps)).
std::vector<double> reference(const Case& c, const std::vector<double>& gain, const std::vector<double>& sd) {
  std::vector<double> y(size_t(c.R) * C);
  for (int r = 0; r < c.R; ++r)
    for (int j = 0; j < C; ++j) {
      double v = -double(c.acc[size_t(r)]) * c.mean[size_t(j)];
      for (int f = 0; f < c.F; ++f) v += double(c.z[size_t(r) * c.ld + c.col + f]) * c.basis[size_t(f) * C + j];
      y[size_t(r) * C + j] = v * gain[size_t(j)] * sd[size_t(j)] / std::sqrt(double(c.var[size_t(j)]) + kEps);
    }
  return y;
}

style::ContentSkip skip_with_gain(const std::vector<float>& gain) {
  style::ContentSkip s = style::ContentSkip::create(0);
  s.gain.value.upload(gain);
  return s;
}

style::ContentSkip::Input input(const Case& c) {
  return {Tensor::from_host(c.z, {c.R, c.ld}), c.col, Tensor::from_host(c.acc, {c.R}),
          Tensor::from_host(c.basis, {c.F, C}), Tensor::from_host(c.mean, {C}), Tensor::from_host(c.var, {C})};
}

// y0 + the skip.
std::vector<float> run(const Case& c, const std::vector<float>& y0, style::ContentSkip::Context* ctx = nullptr,
                       style::ContentSkip* s = nullptr) {
  style::ContentSkip own = skip_with_gain(c.gain);
  Tensor y = Tensor::from_host(y0, {c.R, C});
  (s ? *s : own).forward_add(input(c), Tensor::from_host(c.std, {C}), y, ctx);
  return y.to_host();
}

}  // namespace

TEST_CASE("content skip: forward adds the reference, Z read at a column offset, on a random and the identity basis") {
  for (const Case& c : {random_case(37, 20, 32, 10), random_case(5, C, 0, 20, true), random_case(1, 3, 7, 30)}) {
    CAPTURE(c.F);
    const auto y0 = testing::random_normal(size_t(c.R) * C, 99);
    const auto got = run(c, y0);
    auto want = reference(c, to_double(c.gain), to_double(c.std));
    for (size_t i = 0; i < want.size(); ++i) want[i] += y0[i];
    check_close(got, want, 1e-4, 1e-5, "content skip forward");
  }
}

TEST_CASE("content skip: without a basis Z is the features themselves: the identity basis's output and gradients") {
  const Case c = random_case(19, C, 0, 90, true);
  const auto G = testing::random_normal(size_t(c.R) * C, 91);
  std::vector<std::vector<float>> out, dstd, dgain;
  for (const bool explicit_identity : {true, false}) {
    style::ContentSkip s = skip_with_gain(c.gain);
    style::ContentSkip::Input in = input(c);
    if (!explicit_identity) in.basis = Tensor();
    Tensor y = Tensor::zeros({c.R, C});
    style::ContentSkip::Context ctx;
    s.forward_add(in, Tensor::from_host(c.std, {C}), y, &ctx);
    out.push_back(y.to_host());
    dstd.push_back(s.backward(ctx, Tensor::from_host(G, {c.R, C})).to_host());
    dgain.push_back(s.gain.grad.to_host());
  }
  check_close(out[1], to_double(out[0]), 1e-5, 1e-6, "output");
  check_close(dstd[1], to_double(dstd[0]), 1e-4, 1e-5, "d std");
  check_close(dgain[1], to_double(dgain[0]), 1e-4, 1e-5, "d gain");
}

TEST_CASE("content skip: the gain's and the style std's gradients against central differences of <G, y>") {
  const Case c = random_case(29, 17, 32, 40);
  const auto G = testing::random_normal(size_t(c.R) * C, 41);
  const auto Gd = to_double(G);
  style::ContentSkip s = skip_with_gain(c.gain);
  style::ContentSkip::Context ctx;
  run(c, std::vector<float>(size_t(c.R) * C, 0.0f), &ctx, &s);
  const auto dstd = s.backward(ctx, Tensor::from_host(G, {c.R, C})).to_host();
  const auto dgain = s.gain.grad.to_host();
  std::vector<size_t> idx;
  for (size_t j = 0; j < size_t(C); j += 7) idx.push_back(j);
  const auto gd = to_double(c.gain), sd = to_double(c.std);
  const auto fd_gain = testing::finite_difference_at(
      [&](const std::vector<double>& g) { return testing::dot(Gd, reference(c, g, sd)); }, gd, idx, 1e-3);
  const auto fd_std = testing::finite_difference_at(
      [&](const std::vector<double>& v) { return testing::dot(Gd, reference(c, gd, v)); }, sd, idx, 1e-3);
  std::vector<float> got_gain, got_std;
  for (size_t j : idx) {
    got_gain.push_back(dgain[j]);
    got_std.push_back(dstd[j]);
  }
  check_close(got_gain, fd_gain, 1e-3, 1e-4, "d gain");
  check_close(got_std, fd_std, 1e-3, 1e-4, "d std");
  // A second backward adds into the gain's gradient.
  s.backward(ctx, Tensor::from_host(G, {c.R, C}));
  std::vector<double> twice(dgain.size());
  for (size_t j = 0; j < dgain.size(); ++j) twice[j] = 2.0 * dgain[j];
  check_close(s.gain.grad.to_host(), twice, 1e-6, 1e-7, "accumulated d gain");
}

TEST_CASE("content skip: linear in (Z, acc), so it composites along rays; a ray's output is its own row's") {
  // Three samples of one ray with weights w: the skip of sum w_i z_i with acc = sum w_i equals sum_i w_i
  // skip(z_i, 1).
  Case samples = random_case(3, 11, 0, 50);
  const std::vector<float> w = {0.5f, 0.25f, 0.125f};
  samples.acc = {1.0f, 1.0f, 1.0f};
  const auto per_sample = run(samples, std::vector<float>(size_t(3) * C, 0.0f));
  Case ray = samples;
  ray.R = 1;
  ray.z.assign(size_t(ray.ld), 0.0f);
  ray.acc = {w[0] + w[1] + w[2]};
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < ray.ld; ++k) ray.z[size_t(k)] += w[size_t(i)] * samples.z[size_t(i) * ray.ld + k];
  std::vector<double> composited(C, 0.0);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < C; ++j) composited[size_t(j)] += double(w[size_t(i)]) * per_sample[size_t(i) * C + j];
  check_close(run(ray, std::vector<float>(C, 0.0f)), composited, 1e-4, 1e-5, "skip of the composite");
  // Row 1 alone gives row 1 of the three.
  Case one = samples;
  one.R = 1;
  one.z.assign(samples.z.begin() + samples.ld, samples.z.begin() + 2 * samples.ld);
  one.acc = {1.0f};
  const auto alone = run(one, std::vector<float>(C, 0.0f));
  CHECK(alone == std::vector<float>(per_sample.begin() + C, per_sample.begin() + 2 * C));
}

TEST_CASE("content skip hard cases: zero variance, zero style std and empty rays add exactly 0; huge features stay finite") {
  Case c = random_case(6, C, 0, 60, true);
  // Channel 5: every feature exactly at its mean with zero variance (1/sqrt(eps) = 316 multiplies 0).
  // Channel 9: the style's std is 0. Ray 2 kept nothing.
  c.var[5] = 0.0f;
  c.mean[5] = 0.75f;
  for (int r = 0; r < c.R; ++r) {
    c.acc[size_t(r)] = 1.0f;
    c.z[size_t(r) * c.ld + 5] = 0.75f;
  }
  c.std[9] = 0.0f;
  c.acc[2] = 0.0f;
  for (int k = 0; k < c.ld; ++k) c.z[size_t(2) * c.ld + k] = 0.0f;
  const auto y = run(c, std::vector<float>(size_t(c.R) * C, 0.0f));
  for (int r = 0; r < c.R; ++r) {
    CHECK(y[size_t(r) * C + 5] == 0.0f);
    CHECK(y[size_t(r) * C + 9] == 0.0f);
  }
  bool empty_ray = true;
  for (int j = 0; j < C; ++j) empty_ray &= y[size_t(2) * C + j] == 0.0f;
  CHECK(empty_ray);
  // Features of 1e15 (and their statistics): float still holds the output.
  Case huge = random_case(4, 8, 32, 70);
  for (float& v : huge.z) v *= 1e15f;
  for (float& v : huge.mean) v *= 1e15f;
  for (float& v : huge.var) v *= 1e30f;
  const auto yh = run(huge, std::vector<float>(size_t(huge.R) * C, 0.0f));
  CHECK(testing::all_finite(yh));
  check_close(yh, reference(huge, to_double(huge.gain), to_double(huge.std)), 1e-4, 1e-4, "huge features");
}

TEST_CASE("content skip: bad shapes and non-finite features give errors naming it") {
  const Case c = random_case(4, 8, 32, 80);
  style::ContentSkip s = skip_with_gain(c.gain);
  Tensor y = Tensor::zeros({c.R, C});
  style::ContentSkip::Input in = input(c);
  in.col = c.ld - 4;
  testing::expect_error([&] { s.forward_add(in, Tensor::from_host(c.std, {C}), y, nullptr); },
                        "content skip: columns [39, 47) of Z [4, 43]");
  in = input(c);
  in.basis = Tensor::zeros({8, 100});
  testing::expect_error([&] { s.forward_add(in, Tensor::from_host(c.std, {C}), y, nullptr); },
                        "content skip: the basis must be [F, 256]");
  // A NaN among the composited features: an error naming the skip, not a NaN map.
  Case bad = c;
  bad.z[size_t(bad.ld + bad.col + 2)] = std::nanf("");  // row 1, inside Z
  testing::expect_error([&] { s.forward_add(input(bad), Tensor::from_host(c.std, {C}), y, nullptr); },
                        "content skip: the styled features are not finite");
  in = input(c);
  in.acc = Tensor::zeros({3});
  testing::expect_error([&] { s.forward_add(in, Tensor::from_host(c.std, {C}), y, nullptr); }, "content skip");
}
