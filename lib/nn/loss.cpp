// Losses (kernels/loss.cl): MSE and the AdaIN style loss, forward and backward (w.r.t. the first input).
#include <string>

#include "host/error.hpp"
#include "host/launch.hpp"
#include "lib/nn/checks.hpp"
#include "lib/nn/norm_internal.hpp"
#include "lib/nn/ops.hpp"
#include "lib/nn/reduce_internal.hpp"
#include "lib/nn/reduce_path.hpp"

namespace stylerf::nn {

using host::Error;
using host::launch;

namespace {
int expect_pair(const Tensor& a, const Tensor& b, const char* op) {
  const int n = expect_flat(a, op, "a");
  expect_flat(b, op, "b");
  host::expect_shape(b, a.shape(), op, "b");
  if (n == 0) throw Error(std::string(op) + ": a is empty (shape " + host::shape_str(a.shape()) + ")");
  return n;
}
}  // namespace

// ---- MSE ---------------------------------------------------------------------------------------

Tensor mse_forward(const Tensor& a, const Tensor& b) {
  const int n = expect_pair(a, b, "mse_forward");
  const detail::Partition p = detail::partition(n);
  Tensor partials({p.parts}, "mse partials");
  if (detail::use_group_reductions())
    detail::launch_group_reduce("sqdiff_partials_group", size_t(p.parts), 1, a, b, partials, n, p.chunk);
  else
    launch("loss", "sqdiff_partials", {size_t(p.parts)}, a, b, partials, n, p.chunk);
  return detail::finish_sum(partials, p.parts, static_cast<float>(1.0 / n));
}

Tensor mse_backward(const Tensor& a, const Tensor& b, float dloss) {
  const int n = expect_pair(a, b, "mse_backward");
  Tensor da(a.shape(), "mse_backward da");
  launch("loss", "mse_backward", {size_t((n + 63) / 64)}, a, b, da, n, static_cast<float>(2.0 * dloss / n));
  return da;
}

// ---- AdaIN style loss --------------------------------------------------------------------------

namespace {
void expect_style_target(const Tensor& a, const StyleTarget& b, const char* op) {
  const ChannelDims da = expect_nchw(a, op, "a");
  if (!b.stats.mean.defined() || !b.stats.std.defined() || !b.mean_lo.defined())
    throw Error(std::string(op) + ": the style target is empty (make it with style_target)");
  const Shape want{da.n, da.c};
  host::expect_shape(b.stats.mean, want, op, "the target's mean");
  host::expect_shape(b.stats.std, want, op, "the target's std");
  host::expect_shape(b.mean_lo, want, op, "the target's mean residual");
}
}  // namespace

StyleTarget style_target(const Tensor& b, float eps) {
  expect_nchw(b, "style_target", "b");
  detail::PreciseStats p = detail::channel_stats_precise(b, eps, "style_target", "b");
  return StyleTarget{std::move(p.stats), std::move(p.mean_lo)};
}

Tensor style_loss_forward(const Tensor& a, const StyleTarget& b, float eps) {
  const char* op = "style_loss_forward";
  expect_style_target(a, b, op);
  const detail::PreciseStats pa = detail::channel_stats_precise(a, eps, op, "a");
  const int nc = static_cast<int>(pa.stats.mean.numel());
  Tensor out({1}, "style loss");
  launch("loss", "style_loss_forward", {1}, pa.stats.mean, pa.mean_lo, pa.stats.std, b.stats.mean, b.mean_lo,
         b.stats.std, out, nc);
  return out;
}

Tensor style_loss_backward(const Tensor& a, const StyleTarget& b, float dloss, float eps) {
  const char* op = "style_loss_backward";
  expect_style_target(a, b, op);
  const detail::PreciseStats pa = detail::channel_stats_precise(a, eps, op, "a");
  const int nc = static_cast<int>(pa.stats.mean.numel());
  Tensor dmean(pa.stats.mean.shape(), "style loss dmean"), dstd(pa.stats.mean.shape(), "style loss dstd");
  launch("loss", "style_loss_stat_grads", {size_t(nc)}, pa.stats.mean, pa.mean_lo, pa.stats.std, b.stats.mean,
         b.mean_lo, b.stats.std, dmean, dstd, nc, static_cast<float>(2.0 * dloss / nc));
  return detail::channel_stats_backward_precise(a, pa.stats, pa.mean_lo, dmean, dstd, op);
}

namespace {
void expect_style_pair(const Tensor& a, const Tensor& b, const char* op) {
  const ChannelDims da = expect_nchw(a, op, "a");
  const ChannelDims db = expect_nchw(b, op, "b");
  if (da.n != db.n || da.c != db.c)
    throw Error(std::string(op) + ": a has shape " + host::shape_str(a.shape()) + " and b " +
                host::shape_str(b.shape()) + ": N and C must match (H, W may differ)");
}
}  // namespace

Tensor style_loss_forward(const Tensor& a, const Tensor& b, float eps) {
  expect_style_pair(a, b, "style_loss_forward");
  return style_loss_forward(a, style_target(b, eps), eps);
}

Tensor style_loss_backward(const Tensor& a, const Tensor& b, float dloss, float eps) {
  expect_style_pair(a, b, "style_loss_backward");
  return style_loss_backward(a, style_target(b, eps), dloss, eps);
}

}  // namespace stylerf::nn
