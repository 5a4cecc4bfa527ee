// Channel statistics, instance norm and AdaIN (also towards given statistics: adain_to_stats)
// (kernels/norm.cl): forward against a double reference,
// backward against central finite differences of that reference, and the hard cases (constant
// channels, huge and tiny magnitudes, mean 1e4 with std 1e-2, HW = 1, bad shapes).
#include <doctest/doctest.h>

#include <cmath>
#include <string>

#include "host/error.hpp"
#include "host/tensor.hpp"
#include "lib/nn/ops.hpp"
#include "tests/norm_reference.hpp"
#include "tests/testing.hpp"

using namespace stylerf;
using testing::expect_error;
using host::Shape;
using host::Tensor;
using testing::check_close;
using testing::finite_difference;
using testing::to_double;

namespace {

constexpr double kEps = nn::kStatsEps;

struct Input {
  Shape shape;
  std::vector<float> data;
  int nc, hw;
  Tensor t;
};
Input make(Shape shape, std::vector<float> data) {
  Input in{shape, std::move(data), int(shape[0] * shape[1]), int(shape[2] * shape[3]), {}};
  in.t = Tensor::from_host(in.data, shape);
  return in;
}
Input normal(Shape shape, uint64_t seed, float stddev = 1.0f, float mean = 0.0f) {
  return make(shape, testing::random_normal(size_t(host::shape_numel(shape)), seed, stddev, mean));
}

// Gradient tolerance: float backward vs double finite differences. Relative 1e-3 of each element plus
// 1e-4 of the largest gradient (elements near zero lose relative accuracy to cancellation).
void check_grad(const std::vector<float>& got, const std::vector<double>& want, const std::string& what,
                double rtol = 1e-3, double atol_frac = 1e-4) {
  check_close(got, want, rtol, atol_frac * testing::ref::max_abs(want) + 1e-30, what);
}

// Forward and backward of channel statistics on one input; h is the finite-difference step.
void check_stats(const Input& in, double eps, double rtol_mean, double rtol_std, double h, const std::string& what) {
  nn::ChannelStats s = nn::channel_stats_forward(in.t, float(eps));
  const auto xd = to_double(in.data);
  const auto r = testing::ref::channel_stats(xd, in.nc, in.hw, eps);
  // A mean near 0 of data of size |x| carries rounding on the scale of |x|: rtol_mean of max |x| absolute.
  check_close(s.mean.to_host(), r.mean, rtol_mean, rtol_mean * testing::ref::max_abs(xd), what + " mean");
  check_close(s.std.to_host(), r.std, rtol_std, 0.0, what + " std");

  // Backward: L = <gm, mean> + <gs, std>.
  const auto gm = testing::random_normal(size_t(in.nc), 11), gs = testing::random_normal(size_t(in.nc), 12);
  Tensor dx = nn::channel_stats_backward(in.t, s, Tensor::from_host(gm, {in.shape[0], in.shape[1]}),
                                         Tensor::from_host(gs, {in.shape[0], in.shape[1]}));
  auto f = [&](const std::vector<double>& x) {
    auto st = testing::ref::channel_stats(x, in.nc, in.hw, eps);
    return testing::dot(st.mean, to_double(gm)) + testing::dot(st.std, to_double(gs));
  };
  check_grad(dx.to_host(), finite_difference(f, xd, h), what + " d(stats)/dx");
}

void check_instance_norm(const Input& in, double eps, double atol_y, double h, const std::string& what) {
  nn::ChannelStats s;
  Tensor y = nn::instance_norm_forward(in.t, &s, float(eps));
  const auto xd = to_double(in.data);
  // y is O(1): absolute tolerance.
  check_close(y.to_host(), testing::ref::instance_norm(xd, in.nc, in.hw, eps), 0.0, atol_y, what + " y");
  const auto g = testing::random_normal(in.data.size(), 21);
  Tensor dx = nn::instance_norm_backward(in.t, s, Tensor::from_host(g, in.shape));
  auto f = [&](const std::vector<double>& x) {
    return testing::dot(testing::ref::instance_norm(x, in.nc, in.hw, eps), to_double(g));
  };
  check_grad(dx.to_host(), finite_difference(f, xd, h), what + " instance_norm dx");
}

void check_adain(const Input& c, const Input& st, double eps, double atol_y, double hc, double hs,
                 const std::string& what) {
  Tensor y = nn::adain_forward(c.t, st.t, float(eps));
  const auto cd = to_double(c.data), sd = to_double(st.data);
  const auto yr = testing::ref::adain(cd, sd, c.nc, c.hw, st.hw, eps);
  check_close(y.to_host(), yr, 0.0, atol_y, what + " adain y");
  const auto g = testing::random_normal(c.data.size(), 31);
  nn::AdainGrads gr = nn::adain_backward(c.t, st.t, Tensor::from_host(g, c.shape), float(eps));
  const auto gd = to_double(g);
  auto fc = [&](const std::vector<double>& x) {
    return testing::dot(testing::ref::adain(x, sd, c.nc, c.hw, st.hw, eps), gd);
  };
  auto fs = [&](const std::vector<double>& x) {
    return testing::dot(testing::ref::adain(cd, x, c.nc, c.hw, st.hw, eps), gd);
  };
  const auto dcontent_fd = finite_difference(fc, cd, hc);
  check_grad(gr.dcontent.to_host(), dcontent_fd, what + " adain dcontent");
  check_grad(gr.dstyle.to_host(), finite_difference(fs, sd, hs), what + " adain dstyle");

  // AdaIN towards given statistics (the style's, as floats): the same y and d content; the target is a
  // constant. The float target's rounding is far inside atol_y.
  const auto rs = testing::ref::channel_stats(sd, st.nc, st.hw, eps);
  const std::vector<float> tmean(rs.mean.begin(), rs.mean.end()), tstd(rs.std.begin(), rs.std.end());
  const nn::ChannelStats target{Tensor::from_host(tmean, {c.shape[0], c.shape[1]}),
                                Tensor::from_host(tstd, {c.shape[0], c.shape[1]})};
  check_close(nn::adain_to_stats_forward(c.t, target, float(eps)).to_host(), yr, 0.0, atol_y, what + " adain_to_stats y");
  check_grad(nn::adain_to_stats_backward(c.t, target, Tensor::from_host(g, c.shape), float(eps)).to_host(), dcontent_fd,
             what + " adain_to_stats dcontent");

  // Between given statistics (both constants, floats): the source is the content's own, rounded to float,
  // and the reference applies exactly those constants in double (the op promises that affine map; how close
  // it is to AdaIN depends on the source's rounding, which adain_to_stats' refined mean avoids).
  const auto rc = testing::ref::channel_stats(cd, c.nc, c.hw, eps);
  const std::vector<float> smean(rc.mean.begin(), rc.mean.end()), sstd(rc.std.begin(), rc.std.end());
  const nn::ChannelStats source{Tensor::from_host(smean, {c.shape[0], c.shape[1]}),
                                Tensor::from_host(sstd, {c.shape[0], c.shape[1]})};
  std::vector<double> yb(cd.size());
  for (int64_t p = 0; p < c.nc; ++p)
    for (int64_t i = 0; i < c.hw; ++i)
      yb[size_t(p * c.hw + i)] = (cd[size_t(p * c.hw + i)] - double(smean[size_t(p)])) / double(sstd[size_t(p)]) *
                                     double(tstd[size_t(p)]) +
                                 double(tmean[size_t(p)]);
  check_close(nn::adain_between_stats_forward(c.t, source, target).to_host(), yb, 1e-6, atol_y,
              what + " adain_between_stats y");
}


}  // namespace

TEST_CASE("channel stats: forward and backward on small random data (HW with a tail, several blocks)") {
  // Means to 1e-6 relative (plus the data's spread: mean of N(0.5,1) is not near 0), stds 1e-5.
  check_stats(normal({2, 3, 5, 4}, 1, 1.0f, 0.5f), kEps, 1e-5, 1e-5, 1e-4, "[2,3,5,4]");
  // 1517 = 189 float8 + 5: three accumulation blocks and a scalar tail.
  Input big = normal({1, 2, 37, 41}, 2, 2.0f, -3.0f);
  nn::ChannelStats s = nn::channel_stats_forward(big.t);
  const auto r = testing::ref::channel_stats(to_double(big.data), big.nc, big.hw, kEps);
  check_close(s.mean.to_host(), r.mean, 1e-6, 0.0, "[1,2,37,41] mean");
  check_close(s.std.to_host(), r.std, 1e-6, 0.0, "[1,2,37,41] std");
}

TEST_CASE("channels longer than a chunk (several work-items a channel): stats, instance norm, AdaIN, fwd and bwd") {
  // 70 x 61 = 4270 floats a channel: three chunks of <= 1424 (lib/nn/norm.cpp), the last with a scalar tail.
  Input in = normal({1, 2, 70, 61}, 7, 1.5f, 0.4f);
  check_stats(in, kEps, 1e-5, 1e-5, 1e-4, "[1,2,70,61]");
  check_instance_norm(in, kEps, 1e-5, 1e-4, "[1,2,70,61]");
  check_adain(in, normal({1, 2, 65, 66}, 8, 2.0f, -1.0f), kEps, 1e-5, 1e-4, 1e-4, "content [1,2,70,61], style [1,2,65,66]");
}

TEST_CASE("instance norm: forward and backward") {
  check_instance_norm(normal({2, 3, 5, 4}, 3, 1.5f, 0.7f), kEps, 1e-5, 1e-4, "[2,3,5,4]");
  check_instance_norm(normal({1, 2, 9, 11}, 4), kEps, 1e-5, 1e-4, "[1,2,9,11]");
}

TEST_CASE("AdaIN: forward and backward, style of another size") {
  check_adain(normal({2, 3, 5, 4}, 5, 1.0f, 0.3f), normal({2, 3, 7, 3}, 6, 2.0f, -1.0f), kEps, 1e-5, 1e-4, 1e-4,
              "content [2,3,5,4], style [2,3,7,3]");
}

TEST_CASE("constant channels: std = sqrt(eps), no NaN, gradients match the eps-including reference") {
  // Channel 0 is 0.1 (not a binary fraction: its float sum is inexact), channel 1 is 3, channel 2 is 0;
  // the others random. h is small because near var = 0 the reference curves on the scale of sqrt(eps).
  Input in = normal({2, 3, 5, 4}, 7);
  for (int i = 0; i < 20; ++i) {
    in.data[i] = 0.1f;
    in.data[20 + i] = 3.0f;
    in.data[40 + i] = 0.0f;
  }
  in.t = Tensor::from_host(in.data, in.shape);
  nn::ChannelStats s = nn::channel_stats_forward(in.t);
  const auto sd = s.std.to_host();
  for (int c = 0; c < 3; ++c) CHECK(sd[c] == doctest::Approx(std::sqrt(kEps)).epsilon(1e-6));
  check_stats(in, kEps, 1e-6, 1e-5, 1e-6, "constant channels");
  // y of a constant channel is exactly 0 up to the float mean's residual (<= 1 ulp of 0.1 / sqrt(eps)).
  check_instance_norm(in, kEps, 1e-5, 1e-6, "constant channels");
  Input st = normal({2, 3, 7, 3}, 8);
  for (int i = 0; i < 21; ++i) st.data[21 + i] = -2.0f;  // a constant style channel too
  st.t = Tensor::from_host(st.data, st.shape);
  check_adain(in, st, kEps, 1e-5, 1e-6, 1e-6, "constant channels");
}

TEST_CASE("HW = 1: every channel is constant") {
  Input in = normal({2, 3, 1, 1}, 9);
  check_stats(in, kEps, 1e-7, 1e-6, 1e-6, "HW=1");
  check_instance_norm(in, kEps, 1e-6, 1e-6, "HW=1");
  check_adain(in, normal({2, 3, 2, 2}, 10), kEps, 1e-5, 1e-6, 1e-5, "HW=1 content");
}

TEST_CASE("large magnitudes 1e6 .. 1e15: relative accuracy holds, no overflow") {
  for (float scale : {1e6f, 1e10f, 1e15f}) {
    const std::string what = "scale " + std::to_string(scale);
    Input in = normal({2, 3, 5, 4}, 13, scale, 0.25f * scale);
    const double h = 1e-4 * scale;
    check_stats(in, kEps, 1e-5, 1e-5, h, what);
    check_instance_norm(in, kEps, 1e-5, h, what);
    check_adain(in, normal({2, 3, 7, 3}, 14, 3 * scale, -scale), kEps, 1e-5 * 3 * scale, h, h, what);
  }
}

TEST_CASE("tiny magnitudes 1e-20: eps dominates, values stay finite and accurate") {
  Input in = normal({2, 3, 5, 4}, 15, 1e-20f, 1e-20f);
  // std = sqrt(var + eps) ~ sqrt(eps) (var ~ 1e-40 is below float's normal range and irrelevant).
  // The reference's differences at h ~ 1e-20 vanish below double rounding of f ~ 1e-2, so the finite
  // differences use h = 1e-6: f is smooth on the scale sqrt(eps) ~ 3e-3, so this still probes the
  // gradient at x ~ 1e-20.
  check_stats(in, kEps, 1e-5, 1e-6, 1e-6, "1e-20");
  nn::ChannelStats s;
  Tensor y = nn::instance_norm_forward(in.t, &s);
  check_close(y.to_host(), testing::ref::instance_norm(to_double(in.data), in.nc, in.hw, kEps), 1e-5, 1e-30,
              "1e-20 instance_norm y (relative)");
  // With eps = 0 and data of size 1e-15 (var 1e-30, still a normal float) the statistics are exact.
  Input small = normal({2, 3, 5, 4}, 16, 1e-15f, 3e-15f);
  check_stats(small, 0.0, 1e-5, 1e-5, 1e-19, "1e-15 eps=0");
  check_instance_norm(small, 0.0, 1e-5, 1e-19, "1e-15 eps=0");
}

TEST_CASE("mean 1e4, std 1e-2: the corrected two-pass statistics and the mean residual keep the digits") {
  // Float spacing near 1e4 is 2^-10 ~ 1e-3, a tenth of the std: a naive float mean (or E[x^2]-E[x]^2)
  // gets std wrong by tens of percent or more. Stated tolerances: mean 1e-7 relative (the float mean's
  // own rounding is 5e-8), std 1e-4 relative, normalised values 1e-4 absolute.
  for (Shape shape : {Shape{2, 3, 5, 4}, Shape{1, 2, 256, 256}}) {
    const std::string what = "mean 1e4 " + host::shape_str(shape);
    Input in = normal(shape, 17, 1e-2f, 1e4f);
    nn::ChannelStats s = nn::channel_stats_forward(in.t);
    const auto xd = to_double(in.data);
    const auto r = testing::ref::channel_stats(xd, in.nc, in.hw, kEps);
    check_close(s.mean.to_host(), r.mean, 1e-7, 0.0, what + " mean");
    check_close(s.std.to_host(), r.std, 1e-4, 0.0, what + " std");
    Tensor y = nn::instance_norm_forward(in.t, nullptr);
    check_close(y.to_host(), testing::ref::instance_norm(xd, in.nc, in.hw, kEps), 0.0, 1e-4, what + " y");
  }
  Input in = normal({2, 3, 5, 4}, 18, 1e-2f, 1e4f);
  check_instance_norm(in, kEps, 1e-4, 1e-6, "mean 1e4");
  // AdaIN output near -1e4 is itself a float with spacing ~1e-3: 1.5 of its ulps absolute (the float
  // style mean's rounding plus the output's).
  check_adain(in, normal({2, 3, 7, 3}, 19, 1e-2f, -1e4f), kEps, 1.5e-3, 1e-6, 1e-6, "mean 1e4");
}

TEST_CASE("channel_stats_backward with a float mean: error bounded by the mean's rounding") {
  // Public channel_stats_backward only has the float mean, so (x - mean) is off by up to half an ulp
  // of the mean (2^-11 near 1e4): the dstd term's error is at most |dstd| * 2^-11 / (HW * std).
  Input in = normal({2, 3, 5, 4}, 20, 1e-2f, 1e4f);
  nn::ChannelStats s = nn::channel_stats_forward(in.t);
  const auto xd = to_double(in.data);
  const auto gm = testing::random_normal(6, 21), gs = testing::random_normal(6, 22);
  Tensor dx = nn::channel_stats_backward(in.t, s, Tensor::from_host(gm, {2, 3}), Tensor::from_host(gs, {2, 3}));
  auto f = [&](const std::vector<double>& x) {
    auto st = testing::ref::channel_stats(x, in.nc, in.hw, kEps);
    return testing::dot(st.mean, to_double(gm)) + testing::dot(st.std, to_double(gs));
  };
  const double bound = 3.0 * std::ldexp(1.0, -11) / (20 * 1e-2);  // |gs| <= 3 here
  check_close(dx.to_host(), finite_difference(f, xd, 1e-6), 1e-3, bound, "float-mean stats backward");
}

TEST_CASE("bad shapes give errors naming the op") {
  Tensor x3 = Tensor::zeros({3, 4, 5});
  Tensor x = Tensor::zeros({2, 3, 4, 4});
  expect_error([&] { nn::channel_stats_forward(x3); }, "channel_stats_forward");
  expect_error([&] { nn::channel_stats_forward(x3); }, "4-D");
  expect_error([&] { nn::channel_stats_forward(Tensor()); }, "undefined");
  expect_error([&] { nn::instance_norm_forward(Tensor::zeros({2, 0, 4, 4})); }, "instance_norm_forward");
  expect_error([&] { nn::channel_stats_forward(x, -1.0f); }, "eps");
  nn::ChannelStats s = nn::channel_stats_forward(x);
  expect_error([&] { nn::instance_norm_backward(x, s, Tensor::zeros({2, 3, 4, 5})); }, "instance_norm_backward");
  expect_error([&] { nn::channel_stats_backward(x, s, Tensor::zeros({3, 2}), Tensor::zeros({2, 3})); },
               "channel_stats_backward: dmean");
  nn::ChannelStats wrong = nn::channel_stats_forward(Tensor::zeros({1, 3, 4, 4}));
  expect_error([&] { nn::instance_norm_backward(x, wrong, x); }, "stats.mean");
  expect_error([&] { nn::adain_forward(x, Tensor::zeros({2, 4, 4, 4})); }, "adain_forward");
  expect_error([&] { nn::adain_backward(x, Tensor::zeros({1, 3, 4, 4}), x); }, "adain_backward");
  expect_error([&] { nn::adain_backward(x, x, Tensor::zeros({2, 3, 4, 3})); }, "adain_backward: dy");
  const nn::ChannelStats t6{Tensor::zeros({2, 3}), Tensor::from_host(std::vector<float>(6, 1.0f), {2, 3})};
  expect_error([&] { nn::adain_to_stats_forward(x, {Tensor::zeros({2, 4}), Tensor::zeros({2, 4})}); },
               "stats.mean");
  expect_error([&] { nn::adain_to_stats_forward(x, {Tensor(), Tensor()}); }, "adain_to_stats_forward: stats.mean / stats.std are undefined");
  expect_error([&] { nn::adain_to_stats_backward(x, t6, Tensor::zeros({2, 3, 4, 3})); }, "adain_to_stats_backward: dy");
}
