// Adam (kernels/optim.cl): several steps against a double reference, the first step's known size,
// zero and extreme gradients, convergence on a quadratic, bad arguments.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "host/error.hpp"
#include "host/tensor.hpp"
#include "lib/nn/ops.hpp"
#include "tests/testing.hpp"

using namespace stylerf;
using host::Tensor;
using testing::check_close;

namespace {

double max_abs(const std::vector<double>& v) {
  double m = 0;
  for (double x : v) m = testing::max_or_nan(m, std::fabs(x));
  return m;
}

struct RefAdam {
  std::vector<double> p, m, v;
  void step(const std::vector<float>& g, int t, const nn::AdamConfig& c) {
    const double b1 = c.beta1, b2 = c.beta2;
    for (size_t i = 0; i < p.size(); ++i) {
      m[i] = b1 * m[i] + (1 - b1) * g[i];
      v[i] = b2 * v[i] + (1 - b2) * double(g[i]) * g[i];
      const double mhat = m[i] / (1 - std::pow(b1, t)), vhat = v[i] / (1 - std::pow(b2, t));
      p[i] -= c.lr * mhat / (std::sqrt(vhat) + c.eps);
    }
  }
};

// Runs `steps` Adam steps on device and in double with the same gradients (scale * N(0,1), new each
// step) and compares p, m, v. Tolerances: m, v 1e-5 relative (float rounding of a short recurrence);
// p 1e-5 relative plus 1e-4 of the accumulated movement lr * steps.
// v_atol: extra absolute tolerance on v where v is subnormal.
void check_against_reference(int n, float grad_scale, int steps, const nn::AdamConfig& cfg, const std::string& what,
                             double v_atol = 0.0) {
  auto p0 = testing::random_normal(size_t(n), 1);
  Tensor p = Tensor::from_host(p0, {n}), m = Tensor::zeros({n}), v = Tensor::zeros({n});
  RefAdam ref{testing::to_double(p0), std::vector<double>(size_t(n)), std::vector<double>(size_t(n))};
  for (int t = 1; t <= steps; ++t) {
    auto g = testing::random_normal(size_t(n), uint64_t(100 + t), grad_scale);
    nn::adam_step(p, Tensor::from_host(g, {n}), m, v, t, cfg);
    ref.step(g, t, cfg);
  }
  const double mscale = max_abs(ref.m), vscale = max_abs(ref.v);
  check_close(m.to_host(), ref.m, 1e-5, 1e-6 * mscale, what + " m");
  check_close(v.to_host(), ref.v, 1e-5, 1e-6 * vscale + v_atol, what + " v");
  check_close(p.to_host(), ref.p, 1e-5, 1e-4 * cfg.lr * steps, what + " p");
}

}  // namespace

TEST_CASE("Adam: ten steps match a double reference (n not a multiple of 4)") {
  nn::AdamConfig cfg;
  cfg.lr = 1e-2f;
  for (int n : {1, 3, 4, 1003}) check_against_reference(n, 1.0f, 10, cfg, "n=" + std::to_string(n));
}

TEST_CASE("Adam: gradients of size 1e15 and 1e-20") {
  nn::AdamConfig cfg;
  cfg.lr = 1e-2f;
  // 1e15: v ~ 1e30 stays finite. 1e-20: v ~ (1 - beta2) 1e-40 ~ 1e-43 is below float's normal range
  // (1.2e-38), where the kernels flush to zero by design (-cl-denorms-are-zero, host/runtime.cpp), so v is
  // checked to FLT_MIN; eps dominates the denominator and p is unaffected.
  check_against_reference(1003, 1e15f, 5, cfg, "grad 1e15");
  check_against_reference(1003, 1e-20f, 5, cfg, "grad 1e-20", double(std::numeric_limits<float>::min()));
}

TEST_CASE("Adam: the first step moves each parameter by lr against the gradient's sign") {
  const int n = 1001;
  auto g = testing::random_normal(size_t(n), 5);
  Tensor p = Tensor::zeros({n}), m = Tensor::zeros({n}), v = Tensor::zeros({n});
  nn::AdamConfig cfg;
  cfg.lr = 0.5f;
  nn::adam_step(p, Tensor::from_host(g, {n}), m, v, 1, cfg);
  // mhat = g, vhat = g^2: step = lr * g / (|g| + eps) = lr * sign(g) up to eps / |g|.
  std::vector<double> want(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) want[size_t(i)] = -0.5 * g[size_t(i)] / (std::fabs(double(g[size_t(i)])) + 1e-8);
  check_close(p.to_host(), want, 1e-6, 0.0, "first step");
}

TEST_CASE("Adam: zero gradient leaves everything unchanged, no NaN") {
  Tensor p = Tensor::full({10}, 2.0f), m = Tensor::zeros({10}), v = Tensor::zeros({10});
  for (int t = 1; t <= 3; ++t) nn::adam_step(p, Tensor::zeros({10}), m, v, t, {});
  for (float x : p.to_host()) CHECK(x == 2.0f);
  for (float x : v.to_host()) CHECK(x == 0.0f);
}

TEST_CASE("Adam minimises a quadratic (device loss and gradient: MSE to a target)") {
  const int n = 4099;
  Tensor target = Tensor::from_host(testing::random_normal(size_t(n), 7, 2.0f), {n});
  Tensor p = Tensor::zeros({n}), m = Tensor::zeros({n}), v = Tensor::zeros({n});
  const float loss0 = nn::mse_forward(p, target).to_host()[0];
  nn::AdamConfig cfg;
  cfg.lr = 0.05f;
  for (int t = 1; t <= 300; ++t) nn::adam_step(p, nn::mse_backward(p, target, 1.0f), m, v, t, cfg);
  const float loss = nn::mse_forward(p, target).to_host()[0];
  MESSAGE("quadratic: loss " << loss0 << " -> " << loss << " after 300 steps");
  CHECK(loss0 > 3.0f);
  CHECK(loss < 1e-3f * loss0);
}

TEST_CASE("Adam: bad arguments give errors naming the op") {
  Tensor p = Tensor::zeros({8}), m = Tensor::zeros({8}), v = Tensor::zeros({8});
  CHECK_THROWS_WITH_AS(nn::adam_step(p, Tensor::zeros({9}), m, v, 1, {}), doctest::Contains("adam_step: grad"),
                       host::Error);
  Tensor v2 = Tensor::zeros({4, 2});
  CHECK_THROWS_WITH_AS(nn::adam_step(p, p, m, v2, 1, {}), doctest::Contains("adam_step: v"),
                       host::Error);
  CHECK_THROWS_WITH_AS(nn::adam_step(p, p, m, v, 0, {}), doctest::Contains("adam_step: step"), host::Error);
  nn::AdamConfig bad;
  bad.beta2 = 1.0f;
  CHECK_THROWS_WITH_AS(nn::adam_step(p, p, m, v, 1, bad), doctest::Contains("adam_step: betas"), host::Error);
}
