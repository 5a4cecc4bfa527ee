// Adam (kernels/optim.cl).
#include <cmath>
#include <string>

#include "host/error.hpp"
#include "host/launch.hpp"
#include "lib/nn/checks.hpp"
#include "lib/nn/ops.hpp"

namespace stylerf::nn {

using host::Error;

void adam_step(Tensor& param, const Tensor& grad, Tensor& m, Tensor& v, int step, const AdamConfig& cfg) {
  const char* op = "adam_step";
  const int n = expect_flat(param, op, "param");
  expect_flat(grad, op, "grad");
  expect_flat(m, op, "m");
  expect_flat(v, op, "v");
  host::expect_shape(grad, param.shape(), op, "grad");
  host::expect_shape(m, param.shape(), op, "m");
  host::expect_shape(v, param.shape(), op, "v");
  if (step < 1) throw Error(std::string(op) + ": step must be >= 1 (bias correction divides by 1 - beta^step), got " +
                            std::to_string(step));
  if (!(cfg.beta1 >= 0.0f && cfg.beta1 < 1.0f) || !(cfg.beta2 >= 0.0f && cfg.beta2 < 1.0f))
    throw Error(std::string(op) + ": betas must be in [0, 1), got beta1 " + std::to_string(cfg.beta1) + ", beta2 " +
                std::to_string(cfg.beta2));
  if (!std::isfinite(cfg.lr) || !(cfg.eps >= 0.0f))
    throw Error(std::string(op) + ": lr must be finite and eps >= 0, got lr " + std::to_string(cfg.lr) + ", eps " +
                std::to_string(cfg.eps));
  // Bias corrections in double: 1 - beta2^t is ~1e-3 at t = 1 and loses digits in float.
  const double bc1 = 1.0 - std::pow(double(cfg.beta1), step);
  const double bc2 = 1.0 - std::pow(double(cfg.beta2), step);
  host::launch("optim", "adam_step", {size_t((n + 63) / 64)}, param, grad, m, v, n, cfg.beta1, cfg.beta2,
               cfg.lr / bc1, 1.0 / std::sqrt(bc2), cfg.eps);
}

}  // namespace stylerf::nn
