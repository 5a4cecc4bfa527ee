// Channel statistics, instance norm and AdaIN (kernels/norm.cl), forward and backward side by side.
#include <algorithm>
#include <cmath>
#include <string>

#include "host/error.hpp"
#include "host/launch.hpp"
#include "lib/nn/reduce_path.hpp"
#include "lib/nn/checks.hpp"
#include "lib/nn/norm_internal.hpp"
#include "lib/nn/ops.hpp"

namespace stylerf::nn {

using host::Error;
using host::launch;

namespace {

void expect_eps(float eps, const char* op) {
  // eps = 0 is allowed (exact statistics) but then a constant channel divides by zero: callers' choice.
  if (!(eps >= 0.0f) || !std::isfinite(eps)) throw Error(std::string(op) + ": eps must be finite and >= 0, got " + std::to_string(eps));
}

// Elementwise launches: one work-item per 64 floats (SPAN in kernels/norm.cl) of a channel.
host::Range chunks(const ChannelDims& d) { return host::Range((d.hw + 63) / 64, d.nc); }

// Channels longer than kStatChunk floats are reduced in chunks of about that size, several work-items a
// channel (kernels/norm.cl, the "chunked" kernels): one work-item per channel over 65536 pixels took
// 62% of an H100's decoder-step kernel time (17 ms at [1,256,256,256], now 0.3 ms). On PoCL the three
// launches cost ~1 ms more there (2.2-2.6 -> 3.2-3.5 ms), which a training step does not show. Shorter
// channels keep the one-launch kernels.
constexpr int kStatChunk = 2048;
struct StatChunks {
  int count, size;
};
StatChunks stat_chunks(int hw) {
  const int count = std::clamp((hw + kStatChunk - 1) / kStatChunk, 1, 256);
  return {count, (hw + count - 1) / count};
}

// Stats of the right shape for x (N,C from x).
void expect_stats(const ChannelStats& s, const ChannelDims& d, const char* op) {
  if (!s.mean.defined() || !s.std.defined()) throw Error(std::string(op) + ": stats.mean / stats.std are undefined");
  host::expect_shape(s.mean, {d.n, d.c}, op, "stats.mean");
  host::expect_shape(s.std, {d.n, d.c}, op, "stats.std");
}

}  // namespace

namespace detail {

PreciseStats channel_stats_precise(const Tensor& x, float eps, const char* op, const char* name) {
  const ChannelDims d = expect_nchw(x, op, name);
  expect_eps(eps, op);
  PreciseStats r;
  r.stats.mean = Tensor({d.n, d.c}, std::string(op) + " mean");
  r.stats.std = Tensor({d.n, d.c}, std::string(op) + " std");
  r.mean_lo = Tensor({d.n, d.c}, std::string(op) + " mean residual");
  const StatChunks ch = stat_chunks(d.hw);
  const bool group = detail::use_group_reductions();
  if (ch.count == 1 && !group) {
    launch("norm", "channel_stats_forward", {size_t(d.nc)}, x, r.stats.mean, r.stats.std, r.mean_lo, d.hw, eps, d.nc);
    return r;
  }
  Tensor psum({d.nc, ch.count}, std::string(op) + " chunk sums"), pd({d.nc, ch.count}, std::string(op) + " chunk d"),
      pq({d.nc, ch.count}, std::string(op) + " chunk d^2");
  if (group) {
    Tensor m0({d.nc}, std::string(op) + " approximate mean");
    detail::launch_group_reduce("channel_sums_group", size_t(ch.count), size_t(d.nc), x, psum, d.hw, ch.size, ch.count);
    launch(detail::kGroupReduceProgram, "channel_mean_group", {size_t(d.nc)}, psum, m0, d.hw, ch.count, d.nc);
    detail::launch_group_reduce("channel_centred_sums_group", size_t(ch.count), size_t(d.nc), x, m0, pd, pq, d.hw,
                                ch.size, ch.count);
    launch(detail::kGroupReduceProgram, "channel_stats_finish_group", {size_t(d.nc)}, m0, pd, pq, r.stats.mean,
           r.stats.std, r.mean_lo, d.hw, ch.count, eps, d.nc);
    return r;
  }
  const host::Range parts(size_t(ch.count), size_t(d.nc));
  launch("norm", "channel_sums_chunked", parts, x, psum, d.hw, ch.size, ch.count);
  launch("norm", "channel_centred_sums_chunked", parts, x, psum, pd, pq, d.hw, ch.size, ch.count);
  launch("norm", "channel_stats_finish", {size_t(d.nc)}, psum, pd, pq, r.stats.mean, r.stats.std, r.mean_lo, d.hw,
         ch.count, eps, d.nc);
  return r;
}

Tensor channel_stats_backward_precise(const Tensor& x, const ChannelStats& stats, const Tensor& mean_lo,
                                      const Tensor& dmean, const Tensor& dstd, const char* op) {
  const ChannelDims d = expect_nchw(x, op, "x");
  expect_stats(stats, d, op);
  if (!dmean.defined() || !dstd.defined()) throw Error(std::string(op) + ": dmean / dstd are undefined");
  host::expect_shape(dmean, {d.n, d.c}, op, "dmean");
  host::expect_shape(dstd, {d.n, d.c}, op, "dstd");
  const bool has_lo = mean_lo.defined();
  Tensor dx(x.shape(), std::string(op) + " dx");
  launch("norm", "channel_stats_backward", chunks(d), x, stats.mean, stats.std, has_lo ? mean_lo : stats.mean, dmean,
         dstd, dx, d.hw, has_lo ? 1 : 0);
  return dx;
}

}  // namespace detail

// ---- channel statistics ----------------------------------------------------------------------

ChannelStats channel_stats_forward(const Tensor& x, float eps) {
  return detail::channel_stats_precise(x, eps, "channel_stats_forward", "x").stats;
}

Tensor channel_stats_backward(const Tensor& x, const ChannelStats& stats, const Tensor& dmean, const Tensor& dstd) {
  // Without the residual, (x - mean) carries the float mean's rounding (see norm_internal.hpp).
  return detail::channel_stats_backward_precise(x, stats, Tensor(), dmean, dstd, "channel_stats_backward");
}

// ---- instance norm ---------------------------------------------------------------------------

Tensor instance_norm_forward(const Tensor& x, ChannelStats* stats_out, float eps) {
  const char* op = "instance_norm_forward";
  const ChannelDims d = expect_nchw(x, op, "x");
  detail::PreciseStats ps = detail::channel_stats_precise(x, eps, op, "x");
  Tensor y(x.shape(), "instance_norm_forward y");
  launch("norm", "instance_norm_forward", chunks(d), x, ps.stats.mean, ps.stats.std, ps.mean_lo, y, d.hw);
  if (stats_out) *stats_out = ps.stats;
  return y;
}

namespace {

// Shared by instance norm and AdaIN backward: per-channel sums, then the elementwise formula scaled
// by gain (undefined: 1). Returns dx; sdy / sdyhat are the per-channel sum(dy) and sum(dy * xhat).
struct NormBackward {
  Tensor dx, sdy, sdyhat;
};
NormBackward norm_backward(const Tensor& x, const ChannelStats& stats, const Tensor& dy, const Tensor& gain,
                           const char* op) {
  const ChannelDims d = expect_nchw(x, op, "x");
  expect_stats(stats, d, op);
  if (!dy.defined()) throw Error(std::string(op) + ": dy is undefined");
  host::expect_shape(dy, x.shape(), op, "dy");
  NormBackward r;
  r.sdy = Tensor({d.n, d.c}, std::string(op) + " sum(dy)");
  r.sdyhat = Tensor({d.n, d.c}, std::string(op) + " sum(dy*xhat)");
  Tensor delta({d.n, d.c}, std::string(op) + " mean residual");
  const StatChunks ch = stat_chunks(d.hw);
  const bool group = detail::use_group_reductions();
  if (ch.count == 1 && !group) {
    launch("norm", "norm_backward_sums", {size_t(d.nc)}, x, stats.mean, stats.std, dy, r.sdy, r.sdyhat, delta, d.hw,
           d.nc);
  } else {
    const std::string name(op);
    Tensor pg({d.nc, ch.count}, name + " chunk sum(dy)"), pgx({d.nc, ch.count}, name + " chunk sum(dy*d)"),
        px({d.nc, ch.count}, name + " chunk sum(d)");
    if (group)
      detail::launch_group_reduce("norm_backward_partials_group", size_t(ch.count), size_t(d.nc), x, stats.mean, dy,
                                  pg, pgx, px, d.hw, ch.size, ch.count);
    else
      launch("norm", "norm_backward_partials", host::Range(size_t(ch.count), size_t(d.nc)), x, stats.mean, dy, pg,
             pgx, px, d.hw, ch.size, ch.count);
    launch("norm", "norm_backward_finish", {size_t(d.nc)}, pg, pgx, px, stats.std, r.sdy, r.sdyhat, delta, d.hw,
           ch.count, d.nc);
  }
  r.dx = Tensor(x.shape(), std::string(op) + " dx");
  const bool has_gain = gain.defined();
  launch("norm", "norm_backward_apply", chunks(d), x, stats.mean, stats.std, has_gain ? gain : stats.std, dy, r.sdy,
         r.sdyhat, delta, r.dx, d.hw, has_gain ? 1 : 0);
  return r;
}

}  // namespace

Tensor instance_norm_backward(const Tensor& x, const ChannelStats& stats, const Tensor& dy) {
  return norm_backward(x, stats, dy, Tensor(), "instance_norm_backward").dx;
}

// ---- AdaIN -----------------------------------------------------------------------------------

namespace {
void expect_same_channels(const ChannelDims& c, const ChannelDims& s, const char* op) {
  if (c.n != s.n || c.c != s.c)
    throw Error(std::string(op) + ": content is [" + std::to_string(c.n) + "," + std::to_string(c.c) +
                ",H,W] but style is [" + std::to_string(s.n) + "," + std::to_string(s.c) +
                ",H',W']: N and C must match (H, W may differ)");
}
}  // namespace

Tensor adain_forward(const Tensor& content, const Tensor& style, float eps) {
  const char* op = "adain_forward";
  const ChannelDims dc = expect_nchw(content, op, "content");
  const ChannelDims ds = expect_nchw(style, op, "style");
  expect_same_channels(dc, ds, op);
  detail::PreciseStats cs = detail::channel_stats_precise(content, eps, op, "content");
  detail::PreciseStats ss = detail::channel_stats_precise(style, eps, op, "style");
  // mean_s is used as stored: y = xhat * std_s + mean_s has the float rounding of y itself anyway.
  Tensor y(content.shape(), "adain_forward y");
  launch("norm", "adain_forward", chunks(dc), content, cs.stats.mean, cs.stats.std, cs.mean_lo, ss.stats.mean,
         ss.stats.std, y, dc.hw);
  return y;
}

AdainGrads adain_backward(const Tensor& content, const Tensor& style, const Tensor& dy, float eps) {
  const char* op = "adain_backward";
  const ChannelDims dc = expect_nchw(content, op, "content");
  const ChannelDims ds = expect_nchw(style, op, "style");
  expect_same_channels(dc, ds, op);
  if (!dy.defined()) throw Error(std::string(op) + ": dy is undefined");
  host::expect_shape(dy, content.shape(), op, "dy");
  detail::PreciseStats cs = detail::channel_stats_precise(content, eps, op, "content");
  detail::PreciseStats ss = detail::channel_stats_precise(style, eps, op, "style");
  // y = xhat_c * std_s + mean_s: dcontent is the instance-norm backward scaled by std_s, and
  // d mean_s = sum(dy), d std_s = sum(dy * xhat_c), which channel_stats_backward carries to the style.
  NormBackward nb = norm_backward(content, cs.stats, dy, ss.stats.std, op);
  AdainGrads g;
  g.dcontent = nb.dx;
  g.dstyle = detail::channel_stats_backward_precise(style, ss.stats, ss.mean_lo, nb.sdy, nb.sdyhat, op);
  return g;
}

Tensor adain_to_stats_forward(const Tensor& content, const ChannelStats& target, float eps) {
  const char* op = "adain_to_stats_forward";
  const ChannelDims dc = expect_nchw(content, op, "content");
  expect_stats(target, dc, op);
  detail::PreciseStats cs = detail::channel_stats_precise(content, eps, op, "content");
  Tensor y(content.shape(), "adain_to_stats_forward y");
  launch("norm", "adain_forward", chunks(dc), content, cs.stats.mean, cs.stats.std, cs.mean_lo, target.mean,
         target.std, y, dc.hw);
  return y;
}

Tensor adain_between_stats_forward(const Tensor& content, const ChannelStats& source, const ChannelStats& target) {
  const char* op = "adain_between_stats_forward";
  const ChannelDims dc = expect_nchw(content, op, "content");
  expect_stats(source, dc, op);
  expect_stats(target, dc, op);
  const Tensor no_lo = Tensor::zeros({dc.n, dc.c}, "adain_between_stats_forward mean_lo");
  Tensor y(content.shape(), "adain_between_stats_forward y");
  launch("norm", "adain_forward", chunks(dc), content, source.mean, source.std, no_lo, target.mean, target.std, y,
         dc.hw);
  return y;
}

Tensor adain_to_stats_backward(const Tensor& content, const ChannelStats& target, const Tensor& dy, float eps) {
  const char* op = "adain_to_stats_backward";
  const ChannelDims dc = expect_nchw(content, op, "content");
  expect_stats(target, dc, op);
  detail::PreciseStats cs = detail::channel_stats_precise(content, eps, op, "content");
  // y = xhat_c * target.std + target.mean: the instance-norm backward scaled by target.std.
  return norm_backward(content, cs.stats, dy, target.std, op).dx;
}

}  // namespace stylerf::nn
