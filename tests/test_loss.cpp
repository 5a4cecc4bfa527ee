// MSE and AdaIN style loss (kernels/loss.cl): forward against a double reference, backward against
// central finite differences of it, hard cases (constant channels, huge/tiny magnitudes, HW = 1) and
// bad shapes.
#include <doctest/doctest.h>

#include <cmath>
#include <limits>
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

std::vector<float> normal(const Shape& s, uint64_t seed, float stddev = 1.0f, float mean = 0.0f) {
  return testing::random_normal(size_t(host::shape_numel(s)), seed, stddev, mean);
}

// Loss values: 1e-5 relative. Gradients vs finite differences: 1e-3 relative + 1e-4 of the largest.
void check_mse(const std::vector<float>& a, const std::vector<float>& b, const Shape& shape, float dloss, double h,
               const std::string& what, bool with_fd = true, double loss_atol = 0.0) {
  Tensor ta = Tensor::from_host(a, shape), tb = Tensor::from_host(b, shape);
  const auto ad = to_double(a), bd = to_double(b);
  Tensor l = nn::mse_forward(ta, tb);
  CHECK(l.shape() == Shape{1});
  check_close(l.to_host(), {testing::ref::mse(ad, bd)}, 1e-5, loss_atol, what + " mse");
  Tensor da = nn::mse_backward(ta, tb, dloss);
  if (with_fd) {
    auto f = [&](const std::vector<double>& x) { return dloss * testing::ref::mse(x, bd); };
    const auto want = finite_difference(f, ad, h);
    check_close(da.to_host(), want, 1e-3, 1e-4 * testing::ref::max_abs(want), what + " mse da");
  } else {
    std::vector<double> want(a.size());  // the analytic gradient in double
    for (size_t i = 0; i < a.size(); ++i) want[i] = 2.0 * dloss * (ad[i] - bd[i]) / double(a.size());
    check_close(da.to_host(), want, 1e-5, 0.0, what + " mse da (analytic)");
  }
}

void check_style(const std::vector<float>& a, const Shape& sa, const std::vector<float>& b, const Shape& sb,
                 float dloss, double h, const std::string& what) {
  const int nc = int(sa[0] * sa[1]), hwa = int(sa[2] * sa[3]), hwb = int(sb[2] * sb[3]);
  Tensor ta = Tensor::from_host(a, sa), tb = Tensor::from_host(b, sb);
  const auto ad = to_double(a), bd = to_double(b);
  Tensor l = nn::style_loss_forward(ta, tb);
  CHECK(l.shape() == Shape{1});
  check_close(l.to_host(), {testing::ref::style_loss(ad, bd, nc, hwa, hwb, kEps)}, 1e-5, 0.0, what + " style loss");
  Tensor da = nn::style_loss_backward(ta, tb, dloss);
  // Against b's statistics measured once: the same numbers, bit for bit.
  const nn::StyleTarget target = nn::style_target(tb);
  CHECK(nn::style_loss_forward(ta, target).to_host() == l.to_host());
  CHECK(nn::style_loss_backward(ta, target, dloss).to_host() == da.to_host());
  auto f = [&](const std::vector<double>& x) { return dloss * testing::ref::style_loss(x, bd, nc, hwa, hwb, kEps); };
  const auto want = finite_difference(f, ad, h);
  check_close(da.to_host(), want, 1e-3, 1e-4 * testing::ref::max_abs(want), what + " style loss da");
}


}  // namespace

TEST_CASE("MSE: forward and backward") {
  const Shape s{2, 3, 5, 4};
  check_mse(normal(s, 1), normal(s, 2, 0.5f, 0.2f), s, 0.7f, 1e-4, "[2,3,5,4]");
  // 100003 elements: 13 partial sums (the last one short) and a scalar tail; no finite differences
  // at this size (the reference gradient is analytic).
  const Shape big{1, 1, 1, 100003};
  check_mse(normal(big, 3), normal(big, 4), big, 1.0f, 0.0, "100003", false);
}

TEST_CASE("MSE: equal inputs give exactly 0 and a zero gradient") {
  const Shape s{2, 3, 5, 4};
  Tensor a = Tensor::from_host(normal(s, 5), s);
  CHECK(nn::mse_forward(a, a).to_host()[0] == 0.0f);
  for (float g : nn::mse_backward(a, a, 3.0f).to_host()) CHECK(g == 0.0f);
}

TEST_CASE("MSE: magnitudes 1e6 .. 1e15 and 1e-20") {
  const Shape s{2, 3, 5, 4};
  for (float scale : {1e6f, 1e10f, 1e15f})
    check_mse(normal(s, 6, scale), normal(s, 7, scale), s, 1.0f, 1e-4 * scale, "scale " + std::to_string(scale));
  // At 1e-20 the loss is ~1e-40, below float's normal range (1.2e-38), where the kernels flush to zero by
  // design (-cl-denorms-are-zero, host/runtime.cpp): the loss is 0, or, on a device that keeps subnormals,
  // right to 1e-3 relative. The gradient (~1e-21) is normal and exact either way.
  Tensor a = Tensor::from_host(normal(s, 8, 1e-20f), s), b = Tensor::from_host(normal(s, 9, 1e-20f), s);
  const double want = testing::ref::mse(to_double(a.to_host()), to_double(b.to_host()));
  const float got = nn::mse_forward(a, b).to_host()[0];
  CHECK(std::isfinite(got));
  CHECK(got >= 0.0f);
  if (got != 0.0f) CHECK(got == doctest::Approx(want).epsilon(1e-3));
  check_mse(a.to_host(), b.to_host(), s, 1.0f, 0.0, "scale 1e-20", false, double(std::numeric_limits<float>::min()));
}

TEST_CASE("style loss: forward and backward, b of another size") {
  const Shape sa{2, 3, 5, 4}, sb{2, 3, 7, 3};
  check_style(normal(sa, 10, 1.0f, 0.3f), sa, normal(sb, 11, 2.0f, -0.5f), sb, 1.3f, 1e-4, "random");
}

TEST_CASE("style loss: constant channels, HW = 1 and large magnitudes") {
  const Shape sa{2, 3, 5, 4}, sb{2, 3, 7, 3};
  auto a = normal(sa, 12);
  for (int i = 0; i < 20; ++i) a[20 + i] = 0.1f;  // std(a) = sqrt(eps) in channel 1
  // Small h: near var = 0 the reference curves on the scale of sqrt(eps).
  check_style(a, sa, normal(sb, 13), sb, 1.0f, 1e-6, "constant channel");
  check_style(normal({2, 3, 1, 1}, 14), {2, 3, 1, 1}, normal(sb, 15), sb, 1.0f, 1e-6, "HW=1");
  for (float scale : {1e6f, 1e10f, 1e15f})
    check_style(normal(sa, 16, scale, 0.5f * scale), sa, normal(sb, 17, 2 * scale), sb, 1.0f, 1e-4 * scale,
                "scale " + std::to_string(scale));
}

TEST_CASE("style loss: mean 1e4, std 1e-2 on both sides") {
  // std differences of ~1e-3 between data around 1e4: only the corrected two-pass statistics see them.
  const Shape sa{2, 3, 5, 4}, sb{2, 3, 7, 3};
  check_style(normal(sa, 18, 1e-2f, 1e4f), sa, normal(sb, 19, 2e-2f, 1e4f), sb, 1.0f, 1e-6, "mean 1e4");
}

TEST_CASE("bad shapes give errors naming the op") {
  Tensor a = Tensor::zeros({2, 3, 4, 4});
  expect_error([&] { nn::mse_forward(a, Tensor::zeros({2, 3, 4, 5})); }, "mse_forward");
  expect_error([&] { nn::mse_backward(a, Tensor::zeros({2, 3, 4, 5}), 1.0f); }, "mse_backward");
  expect_error([&] { nn::mse_forward(a, Tensor()); }, "mse_forward: b is undefined");
  expect_error([&] { nn::style_loss_forward(a, Tensor::zeros({2, 4, 4, 4})); }, "style_loss_forward");
  expect_error([&] { nn::style_loss_backward(Tensor::zeros({3, 4, 4}), a, 1.0f); }, "style_loss_backward");
  expect_error([&] { nn::style_loss_forward(a, nn::StyleTarget{}); }, "style target is empty");
  expect_error([&] { nn::style_loss_forward(a, nn::style_target(Tensor::zeros({1, 5, 4, 4}))); }, "target's mean");
}
