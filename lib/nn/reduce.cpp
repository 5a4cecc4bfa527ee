// Whole-tensor reductions (kernels/reduce.cl), the vectorised axpby (kernels/elementwise.cl) and the
// non-finite check.
#include <algorithm>
#include <string>

#include "host/error.hpp"
#include "host/launch.hpp"
#include "lib/nn/checks.hpp"
#include "lib/nn/ops.hpp"
#include "lib/nn/reduce_internal.hpp"
#include "lib/nn/reduce_path.hpp"

namespace stylerf::nn {

using host::Error;
using host::launch;

namespace detail {

Partition partition(int64_t n) {
  // ~8K elements per work-item keeps stage 2 tiny; at most 1024 parts; at least 1.
  constexpr int64_t kTarget = 8192, kMaxParts = 1024;
  int64_t parts = std::clamp<int64_t>((n + kTarget - 1) / kTarget, 1, kMaxParts);
  int64_t chunk = (n + parts - 1) / parts;
  chunk = std::max<int64_t>((chunk + 7) / 8 * 8, 8);
  parts = std::max<int64_t>((n + chunk - 1) / chunk, 1);
  return {static_cast<int>(parts), static_cast<int>(chunk)};
}

Tensor finish_sum(const Tensor& partials, int parts, float scale) {
  Tensor out({1}, "reduction result");
  launch("reduce", "sum_finish", {1}, partials, out, parts, scale);
  return out;
}

}  // namespace detail

Tensor sum(const Tensor& x) {
  const int n = expect_flat(x, "sum", "x");
  if (n == 0) return Tensor::zeros({1}, "sum result");
  const detail::Partition p = detail::partition(n);
  Tensor partials({p.parts}, "sum partials");
  if (detail::use_group_reductions())
    detail::launch_group_reduce("sum_partials_group", size_t(p.parts), 1, x, partials, n, p.chunk);
  else
    launch("reduce", "sum_partials", {size_t(p.parts)}, x, partials, n, p.chunk);
  return detail::finish_sum(partials, p.parts, 1.0f);
}

float sum_value(const Tensor& x) { return sum(x).to_host()[0]; }

bool has_nonfinite(const Tensor& x) {
  const int n = expect_flat(x, "has_nonfinite", "x");
  if (n == 0) return false;
  const detail::Partition p = detail::partition(n);
  Tensor partials({p.parts}, "has_nonfinite partials");
  launch("reduce", "nonfinite_partials", {size_t(p.parts)}, x, partials, n, p.chunk);
  // Counts are exact in float (each part <= chunk < 2^24; their sum only needs to be > 0).
  return detail::finish_sum(partials, p.parts, 1.0f).to_host()[0] > 0.0f;
}

void axpby(float a, const Tensor& x, float b, Tensor& y) {
  const int n = expect_flat(x, "axpby", "x");
  expect_flat(y, "axpby", "y");
  host::expect_shape(y, x.shape(), "axpby", "y");
  // x and y may share a buffer: each element is read, then written, by the same work-item.
  launch("elementwise", "axpby64", {size_t((n + 63) / 64)}, x, y, a, b, n);
}

bool device_flushes_denormals() {
  Tensor y = Tensor::from_host(std::vector<float>{0.0f}, {1}, "denormal probe");
  axpby(1e-20f, Tensor::from_host(std::vector<float>{1e-20f}, {1}, "denormal probe"), 0.0f, y);
  return y.to_host()[0] == 0.0f;  // 1e-40 is a denormal: kept, or flushed to 0
}

}  // namespace stylerf::nn
