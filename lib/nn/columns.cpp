// Two stages: column_partial_sums over blocks of rows (deterministic: the split depends on the shape
// only), then linear_bias_grad adds the partials; column_finish scales (and takes a root).
#include "lib/nn/columns.hpp"

#include <algorithm>
#include <string>

#include "host/error.hpp"
#include "host/launch.hpp"

namespace stylerf::nn {
namespace {

using host::Error;

enum Mode { kSum = 0, kSquaredDeviation = 1, kDot = 2 };

void check_matrix(const char* op, const Tensor& a) {
  if (!a.defined()) throw Error(std::string(op) + ": input is undefined");
  if (a.ndim() != 2) throw Error(std::string(op) + ": input must be [rows, cols], got " + host::shape_str(a.shape()));
}

Tensor partial_then_total(const char* op, const Tensor& a, cl_mem b, cl_mem center, Mode mode) {
  check_matrix(op, a);
  const int rows = int(a.dim(0)), cols = int(a.dim(1));
  // About 2048 rows a part, at most 256 parts: enough work-items for any device, few partials to add.
  const int parts = std::clamp((rows + 2047) / 2048, 1, 256);
  const int per_part = (rows + parts - 1) / parts;
  Tensor partial({parts, cols}, std::string(op) + " partial sums");
  host::launch("columns", "column_partial_sums", {size_t((cols + 7) / 8), size_t(parts)}, a, b, center, partial, rows,
               cols, per_part, int(mode));
  Tensor total({cols}, std::string(op) + " output");
  host::launch("linear", "linear_bias_grad", {size_t((cols + 7) / 8)}, partial, total, parts, cols, 0);
  return total;
}

Tensor finish(const Tensor& in, float scale, bool take_sqrt, const char* what) {
  Tensor out(in.shape(), what);
  host::launch("columns", "column_finish", {size_t(in.numel())}, in, out, int(in.numel()), scale, take_sqrt ? 1 : 0);
  return out;
}

}  // namespace

Tensor column_sum(const Tensor& a) { return partial_then_total("column_sum", a, nullptr, nullptr, kSum); }

Tensor column_dot(const Tensor& a, const Tensor& b) {
  check_matrix("column_dot", a);
  host::expect_shape(b, a.shape(), "column_dot", "b");
  return partial_then_total("column_dot", a, b.mem(), nullptr, kDot);
}

Tensor column_mean(const Tensor& a) {
  const Tensor s = column_sum(a);
  return finish(s, 1.0f / float(a.dim(0)), false, "column_mean");
}

namespace {
Tensor sum_sq_dev(const char* op, const Tensor& a, const Tensor& mean, int ddof) {
  check_matrix(op, a);
  host::expect_shape(mean, {a.dim(1)}, op, "mean");
  if (a.dim(0) - ddof <= 0)
    throw Error(std::string(op) + ": " + std::to_string(a.dim(0)) + " rows leave no degrees of freedom with ddof " +
                std::to_string(ddof));
  return partial_then_total(op, a, nullptr, mean.mem(), kSquaredDeviation);
}
}  // namespace

Tensor column_variance(const Tensor& a, const Tensor& mean, int ddof) {
  const Tensor s = sum_sq_dev("column_variance", a, mean, ddof);
  return finish(s, 1.0f / float(a.dim(0) - ddof), false, "column_variance");
}

Tensor column_std(const Tensor& a, const Tensor& mean, int ddof) {
  const Tensor s = sum_sq_dev("column_std", a, mean, ddof);
  return finish(s, 1.0f / float(a.dim(0) - ddof), true, "column_std");
}

}  // namespace stylerf::nn
