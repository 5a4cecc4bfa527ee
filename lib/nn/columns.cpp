// Two stages: column_partial_sums (or, for images, channel_partial_sums) over blocks of rows or pixels
// (deterministic: the split depends on the shape only), then linear_bias_grad adds the partials;
// column_finish scales (and takes a root).
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

// About 2048 rows a part, at most 4096 parts: enough work-items for a GPU, few partials to add (nn::linear's
// bias gradient over SICT's 3.1M points, one work-item per 8 columns over all rows, took ~1 s of an H100's
// 1.4 s style step). The split depends on the shape only, so results do not depend on the device.
int parts_for(int rows) { return std::clamp((rows + 2047) / 2048, 1, 4096); }

// Adds the rows of partial [parts, cols] in a fixed order into out (or overwrites it).
void add_partials(const Tensor& partial, Tensor& out, bool accumulate) {
  const int parts = int(partial.dim(0)), cols = int(partial.dim(1));
  host::launch("linear", "linear_bias_grad", {size_t((cols + 7) / 8)}, partial, out, parts, cols, accumulate ? 1 : 0);
}

void partial_then_total_into(const char* op, const Tensor& a, cl_mem b, cl_mem center, Mode mode, Tensor& out,
                             bool accumulate) {
  const int rows = int(a.dim(0)), cols = int(a.dim(1));
  const int parts = parts_for(rows);
  if (parts == 1 && mode == kSum) {  // one part: the total is the sum itself
    add_partials(a, out, accumulate);
    return;
  }
  const int per_part = (rows + parts - 1) / parts;
  Tensor partial({parts, cols}, std::string(op) + " partial sums");
  host::launch("columns", "column_partial_sums", {size_t((cols + 7) / 8), size_t(parts)}, a, b, center, partial, rows,
               cols, per_part, int(mode));
  add_partials(partial, out, accumulate);
}

Tensor partial_then_total(const char* op, const Tensor& a, cl_mem b, cl_mem center, Mode mode) {
  check_matrix(op, a);
  Tensor total({a.dim(1)}, std::string(op) + " output");
  partial_then_total_into(op, a, b, center, mode, total, false);
  return total;
}

Tensor finish(const Tensor& in, float scale, bool take_sqrt, const char* what) {
  Tensor out(in.shape(), what);
  host::launch("columns", "column_finish", {size_t(in.numel())}, in, out, int(in.numel()), scale, take_sqrt ? 1 : 0);
  return out;
}

}  // namespace

Tensor column_sum(const Tensor& a) { return partial_then_total("column_sum", a, nullptr, nullptr, kSum); }

void column_sum_into(const Tensor& a, Tensor& out, bool accumulate) {
  check_matrix("column_sum_into", a);
  host::expect_shape(out, {a.dim(1)}, "column_sum_into", "out");
  partial_then_total_into("column_sum_into", a, nullptr, nullptr, kSum, out, accumulate);
}

Tensor image_channel_sum(const Tensor& x) {
  if (!x.defined() || x.ndim() != 4)
    throw Error("image_channel_sum: input must be [N, C, H, W], got " +
                (x.defined() ? host::shape_str(x.shape()) : std::string("undefined")));
  const int N = int(x.dim(0)), C = int(x.dim(1)), hw = int(x.dim(2) * x.dim(3));
  // Each image's channel plane is cut into chunks of about 2048 pixels: part n * chunks + k.
  const int chunks = std::max(1, (hw + 2047) / 2048), chunk = (hw + chunks - 1) / chunks;
  Tensor partial({N * chunks, C}, "image_channel_sum partial sums");
  host::launch("nn", "channel_partial_sums", {size_t(C), size_t(N * chunks)}, x, partial, N, C, hw, chunk, chunks);
  Tensor total({C}, "image_channel_sum output");
  add_partials(partial, total, false);
  return total;
}

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
