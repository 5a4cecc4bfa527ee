// Per-column reductions of a row-major [rows, cols] matrix: the per-channel statistics of rows of features
// (points, rays, style positions) and the sums their backward passes need. kernels/columns.cl.
#pragma once
#include "host/tensor.hpp"

namespace stylerf::nn {

using host::Tensor;

// [cols]: sum over rows of a.
Tensor column_sum(const Tensor& a);
// out (+)= the sum over rows of a: nn::linear's bias gradient (accumulate adds to a Param's gradient).
void column_sum_into(const Tensor& a, Tensor& out, bool accumulate);
// [C]: the sum of x [N, C, H, W] over images and pixels: a convolution's bias gradient.
Tensor image_channel_sum(const Tensor& x);
// [cols]: sum over rows of a * b (same shape).
Tensor column_dot(const Tensor& a, const Tensor& b);
// [cols]: mean over rows.
Tensor column_mean(const Tensor& a);
// [cols]: sum over rows of (a - mean)^2 / (rows - ddof), two-pass (no E[x^2] - E[x]^2 cancellation).
// rows - ddof must be positive.
Tensor column_variance(const Tensor& a, const Tensor& mean, int ddof);
// [cols]: the square root of column_variance (no eps: a constant column gives exactly 0).
Tensor column_std(const Tensor& a, const Tensor& mean, int ddof);

}  // namespace stylerf::nn
