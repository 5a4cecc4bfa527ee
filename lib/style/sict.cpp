#include "lib/style/sict.hpp"

#include <cmath>
#include <random>

#include "host/error.hpp"
#include "host/launch.hpp"
#include "lib/nn/columns.hpp"
#include "lib/nn/linear.hpp"
#include "lib/nn/reduce_path.hpp"

namespace stylerf::style {

using host::Error;

std::string sict_build_options() { return "-DSICT_EMBED=" + std::to_string(Sict::kEmbed); }

template <class... Args>
static void launch_sict(const char* kernel, const host::Range& global, const Args&... args) {
  host::launch_with_local("sict", kernel, sict_build_options(), global, host::Range(0), args...);
}

// The channel attention's kernel pair: one work-item per point (CPU devices), or a work-group of
// kAttentionRows points x kEmbed lanes (kernels/sict.cl, "3b"), on the reductions' path choice.
constexpr int kAttentionLanes = 256, kAttentionRows = kAttentionLanes / Sict::kEmbed;
template <class... Args>
static void launch_attention(const char* kernel, int rows, const Args&... args) {
  if (!nn::detail::use_group_reductions()) {
    launch_sict(kernel, {size_t(rows)}, args..., rows);
    return;
  }
  const size_t groups = (size_t(rows) + kAttentionRows - 1) / kAttentionRows;
  host::launch_with_local("sict", (std::string(kernel) + "_group").c_str(), sict_build_options(),
                          {groups * kAttentionLanes}, host::Range(size_t(kAttentionLanes)), args..., rows);
}

SictMode parse_sict_mode(const std::string& s) {
  if (s == "volume-adaptive") return SictMode::VolumeAdaptive;
  if (s == "vanilla-in") return SictMode::VanillaIn;
  if (s == "none") return SictMode::None;
  throw Error("unknown SICT mode '" + s + "' (expected volume-adaptive, vanilla-in or none)");
}

const char* sict_mode_name(SictMode m) {
  switch (m) {
    case SictMode::VolumeAdaptive: return "volume-adaptive";
    case SictMode::VanillaIn: return "vanilla-in";
    case SictMode::None: return "none";
  }
  return "?";
}

namespace {
void check_rows(const char* op, const Tensor& x, int cols) {
  if (!x.defined()) throw Error(std::string(op) + ": input is undefined");
  if (x.ndim() != 2 || x.dim(1) != cols)
    throw Error(std::string(op) + ": expected [K, " + std::to_string(cols) + "], got " + host::shape_str(x.shape()));
  if (x.dim(0) == 0) throw Error(std::string(op) + ": no points (skip an empty batch before calling)");
}
}  // namespace

Tensor point_norm_forward(const Tensor& x, const Tensor& mean, const Tensor& var, float eps) {
  if (!x.defined() || x.ndim() != 2) throw Error("point_norm_forward: x must be [K, C]");
  const int rows = int(x.dim(0)), cols = int(x.dim(1));
  host::expect_shape(mean, {cols}, "point_norm_forward", "mean");
  host::expect_shape(var, {cols}, "point_norm_forward", "var");
  Tensor y(x.shape(), "point_norm output");
  launch_sict("point_norm_forward", {size_t((cols + 7) / 8), size_t(rows)}, x, mean, var, y, rows, cols, eps);
  return y;
}

Tensor point_norm_backward(const Tensor& y, const Tensor& var, const Tensor& dy, float eps, bool fixed) {
  if (!y.defined() || y.ndim() != 2) throw Error("point_norm_backward: y must be [K, C]");
  const int rows = int(y.dim(0)), cols = int(y.dim(1));
  host::expect_shape(dy, y.shape(), "point_norm_backward", "dy");
  host::expect_shape(var, {cols}, "point_norm_backward", "var");
  Tensor sum_dy, sum_dyy;
  if (!fixed) {
    sum_dy = nn::column_sum(dy);
    sum_dyy = nn::column_dot(dy, y);
  } else {
    sum_dy = sum_dyy = var;  // unused by the kernel
  }
  Tensor dx(y.shape(), "point_norm dx");
  launch_sict("point_norm_backward", {size_t((cols + 7) / 8), size_t(rows)}, y, var, dy, sum_dy, sum_dyy, dx,
               rows, cols, eps, fixed ? 1 : 0);
  return dx;
}

Tensor channel_attention_forward(const Tensor& qkv) {
  check_rows("channel_attention_forward", qkv, 3 * Sict::kEmbed);
  const int rows = int(qkv.dim(0));
  Tensor out({rows, Sict::kEmbed}, "channel attention output");
  launch_attention("channel_attention_forward", rows, qkv, out);
  return out;
}

Tensor channel_attention_backward(const Tensor& qkv, const Tensor& dout) {
  check_rows("channel_attention_backward", qkv, 3 * Sict::kEmbed);
  const int rows = int(qkv.dim(0));
  host::expect_shape(dout, {rows, Sict::kEmbed}, "channel_attention_backward", "dout");
  Tensor d(qkv.shape(), "channel attention dqkv");
  launch_attention("channel_attention_backward", rows, qkv, dout, d);
  return d;
}

Sict Sict::create(SictMode mode, int group, uint64_t seed, const std::string& prefix) {
  Sict s;
  s.mode = mode;
  std::mt19937_64 rng(seed);
  const float bound = 1.0f / std::sqrt(float(kChannels));
  std::uniform_real_distribution<float> u(-bound, bound);
  std::vector<float> w(size_t(kChannels) * 3 * kEmbed), b(3 * kEmbed);
  for (float& v : w) v = u(rng);
  for (float& v : b) v = u(rng);
  s.qkv_w = nn::Param(prefix + "qkv.weight", group, Tensor::from_host(w, {kChannels, 3 * kEmbed}, "sict qkv weight"));
  s.qkv_b = nn::Param(prefix + "qkv.bias", group, Tensor::from_host(b, {3 * kEmbed}, "sict qkv bias"));
  s.running_mean = {prefix + "running_mean", Tensor::zeros({kChannels}, "sict running mean")};
  Tensor ones({kChannels}, "sict running var");
  ones.fill(1.0f);
  s.running_var = {prefix + "running_var", ones};
  return s;
}

Tensor Sict::forward(const Tensor& x, bool training, Context* ctx) const {
  check_rows("sict forward", x, kChannels);
  Tensor normed, mean, var;
  bool batch = false;
  if (mode == SictMode::None) {
    normed = x;
  } else {
    batch = (mode == SictMode::VanillaIn) || training;
    if (batch) {
      mean = nn::column_mean(x);
      var = nn::column_variance(x, mean, 0);  // biased, as the normalisation uses
    } else {
      mean = running_mean.value;
      var = running_var.value;
    }
    normed = point_norm_forward(x, mean, var, kEps);
  }
  Tensor qkv = nn::linear_forward(normed, qkv_w.value, qkv_b.value);
  Tensor out = channel_attention_forward(qkv);
  if (ctx) {
    ctx->x = x;
    ctx->normed = normed;
    ctx->mean = mean;
    ctx->var = var;
    ctx->batch_stats = batch;
    ctx->qkv = qkv;
    ctx->points = x.dim(0);
  }
  return out;
}

// sict_factored.cpp: the weight and bias gradients of a forward_factored context.
void sict_factored_backward(const Sict::Context& ctx, const Tensor& dqkv, nn::Param& qkv_w, nn::Param& qkv_b);

Tensor Sict::backward(const Context& ctx, const Tensor& dy, bool need_dx) {
  const Tensor dqkv = channel_attention_backward(ctx.qkv, dy);
  if (ctx.factored()) {
    if (need_dx) throw Error("sict backward: a forward_factored context gives no dx (the feature field is frozen)");
    sict_factored_backward(ctx, dqkv, qkv_w, qkv_b);
    return Tensor();
  }
  Tensor dnormed = nn::linear_backward(ctx.normed, qkv_w, &qkv_b, dqkv, need_dx);
  if (!need_dx) return Tensor();
  if (mode == SictMode::None) return dnormed;
  return point_norm_backward(ctx.normed, ctx.var, dnormed, kEps, !ctx.batch_stats);
}

void Sict::update_running(const Context& ctx) {
  if (mode != SictMode::VolumeAdaptive || !ctx.batch_stats) return;
  launch_sict("running_stats_update", {size_t(kChannels)}, running_mean.value, running_var.value, ctx.mean,
               ctx.var, kChannels, int(ctx.points), kMomentum);
}

void Sict::collect_params(std::vector<nn::Param*>& out) {
  out.push_back(&qkv_w);
  out.push_back(&qkv_b);
}

void Sict::collect_buffers(std::vector<nn::StateBuffer*>& out) {
  out.push_back(&running_mean);
  out.push_back(&running_var);
}

}  // namespace stylerf::style
