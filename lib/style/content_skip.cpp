#include "lib/style/content_skip.hpp"

#include <cmath>

#include "host/error.hpp"
#include "host/gemm.hpp"
#include "lib/nn/checks.hpp"
#include "lib/nn/columns.hpp"
#include "lib/nn/ops.hpp"
#include "lib/style/dst.hpp"

namespace stylerf::style {

using host::Error;
using host::Trans;

namespace {
constexpr int C = ContentSkip::kChannels;

// Z's columns: the basis's rows, or 256 for the identity (no basis).
int64_t components(const ContentSkip::Input& in) { return in.basis.defined() ? in.basis.dim(0) : C; }

void check_input(const ContentSkip::Input& in) {
  const char* op = "content skip";
  if (!in.z.defined() || in.z.ndim() != 2) throw Error("content skip: Z must be a [R, columns] matrix");
  if (in.basis.defined() && (in.basis.ndim() != 2 || in.basis.dim(1) != C))
    throw Error("content skip: the basis must be [F, 256]");
  const int64_t F = components(in);
  if (in.col < 0 || in.col + F > in.z.dim(1))
    throw Error("content skip: columns [" + std::to_string(in.col) + ", " + std::to_string(in.col + F) + ") of Z " +
                host::shape_str(in.z.shape()));
  host::expect_shape(in.acc, {in.z.dim(0)}, op, "acc");
  host::expect_shape(in.mean, {C}, op, "mean");
  host::expect_shape(in.var, {C}, op, "var");
}
// Z itself [R, 256] where it is the features (the identity basis): it must then be the whole matrix.
const Tensor& identity_input(const ContentSkip::Input& in) {
  if (in.col != 0 || in.z.dim(1) != C) throw Error("content skip: without a basis Z must be the [R, 256] features");
  return in.z;
}
}  // namespace

ContentSkip ContentSkip::create(int group, const std::string& prefix) {
  ContentSkip s;
  s.gain = nn::Param(prefix + "gain", group, Tensor::full({C}, 1.0f, prefix + "gain"));
  return s;
}

void ContentSkip::forward_add(const Input& in, const Tensor& style_std, Tensor& y, Context* ctx) const {
  check_input(in);
  host::expect_shape(style_std, {C}, "content skip", "style std");
  const int R = int(in.z.dim(0)), F = int(components(in)), ld = int(in.z.dim(1));
  host::expect_shape(y, {R, C}, "content skip", "y");
  if (R == 0) return;
  // The [256] vectors on the host: the scale is formed once a map, the [R, 256] work stays on the device.
  const auto mean = in.mean.to_host(), var = in.var.to_host(), g = gain.value.to_host(), sd = style_std.to_host();
  std::vector<float> inv(C), scale(C), shift(C);
  for (int j = 0; j < C; ++j) {
    inv[size_t(j)] = float(1.0 / std::sqrt(double(var[size_t(j)]) + kEps));
    scale[size_t(j)] = g[size_t(j)] * sd[size_t(j)] * inv[size_t(j)];
    shift[size_t(j)] = -scale[size_t(j)] * mean[size_t(j)];
  }
  const Tensor scale_t = Tensor::from_host(scale, {C}, "content skip scale");
  if (in.basis.defined()) {
    const Tensor W = scale_columns(in.basis, scale_t, "content skip weights");
    host::gemm(Trans::No, Trans::No, R, C, F, 1.0f, in.z.mem(), size_t(in.col), ld, W.mem(), 0, C, 1.0f, y.mem(), 0, C);
  } else {  // the identity: Z's 256 columns scaled, no product
    nn::axpby(1.0f, scale_columns(identity_input(in), scale_t, "content skip of the features"), 1.0f, y);
  }
  const Tensor shift_t = Tensor::from_host(shift, {C}, "content skip shift");
  host::gemm(Trans::No, Trans::No, R, C, 1, 1.0f, in.acc.mem(), 0, 1, shift_t.mem(), 0, C, 1.0f, y.mem(), 0, C);
  // As DST's apply: a NaN or an infinity in, or an overflow, is an error here rather than a NaN map downstream.
  if (nn::has_nonfinite(y))
    throw Error("content skip: the styled features are not finite (the composited features, their opacity, "
                "the statistics or the style's std hold a NaN or an infinity, or the product overflows float)");
  if (ctx) *ctx = {in, scale_t, Tensor::from_host(inv, {C}, "content skip 1/sqrt(var + eps)"), style_std};
}

Tensor ContentSkip::backward(const Context& ctx, const Tensor& dy) {
  const Input& in = ctx.in;
  const int R = int(in.z.dim(0)), F = int(components(in)), ld = int(in.z.dim(1));
  host::expect_shape(dy, {R, C}, "content skip backward", "dy");
  // y = Z B diag(scale) - acc (scale * mean): d scale_j = sum_i (Z^T dy)_ij B_ij - mean_j (acc^T dy)_j; with
  // the identity, sum_r Z_rj dy_rj.
  Tensor zb_dy;
  if (in.basis.defined()) {
    Tensor dW({F, C}, "content skip dW");
    host::gemm(Trans::Yes, Trans::No, F, C, R, 1.0f, in.z.mem(), size_t(in.col), ld, dy.mem(), 0, C, 0.0f, dW.mem(),
               0, C);
    zb_dy = nn::column_dot(in.basis, dW);
  } else {
    zb_dy = nn::column_dot(identity_input(in), dy);
  }
  Tensor acc_dy({C}, "content skip acc^T dy");
  host::gemm(Trans::Yes, Trans::No, C, 1, R, 1.0f, dy.mem(), 0, C, in.acc.mem(), 0, 1, 0.0f, acc_dy.mem(), 0, 1);
  const auto bw = zb_dy.to_host(), ad = acc_dy.to_host(), mean = in.mean.to_host(),
             inv = ctx.inv.to_host(), g = gain.value.to_host(), sd = ctx.std.to_host();
  std::vector<float> dgain(C), dstd(C);
  for (int j = 0; j < C; ++j) {
    const double ds = double(bw[size_t(j)]) - double(mean[size_t(j)]) * ad[size_t(j)];
    dgain[size_t(j)] = float(ds * sd[size_t(j)] * inv[size_t(j)]);
    dstd[size_t(j)] = float(ds * g[size_t(j)] * inv[size_t(j)]);
  }
  gain.accumulate(Tensor::from_host(dgain, {C}, "content skip d gain"));
  return Tensor::from_host(dstd, {C}, "content skip d std");
}

}  // namespace stylerf::style
