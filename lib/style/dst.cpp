#include "lib/style/dst.hpp"

#include <cmath>
#include <random>

#include "host/error.hpp"
#include "host/gemm.hpp"
#include "host/launch.hpp"
#include "lib/nn/checks.hpp"
#include "lib/nn/columns.hpp"
#include "lib/nn/linear.hpp"
#include "lib/nn/ops.hpp"

namespace stylerf::style {

using host::Error;
using host::Trans;

namespace {

constexpr int C = Dst::kChannels, E = Dst::kEmbed;

nn::Param uniform_param(const std::string& name, int group, host::Shape shape, int fan_in, std::mt19937_64& rng) {
  const float bound = 1.0f / std::sqrt(float(fan_in));
  std::uniform_real_distribution<float> u(-bound, bound);
  std::vector<float> v(size_t(host::shape_numel(shape)));
  for (float& x : v) x = u(rng);
  return nn::Param(name, group, Tensor::from_host(v, shape, name));
}

Tensor subtract_row_vector(const Tensor& x, const Tensor& v) {
  const int rows = int(x.dim(0)), cols = int(x.dim(1));
  Tensor y(x.shape(), "centred style features");
  host::launch("dst", "subtract_row_vector", {size_t((cols + 7) / 8), size_t(rows)}, x, v, y, rows, cols);
  return y;
}

}  // namespace

Tensor scale_columns(const Tensor& x, const Tensor& v, const char* what) {
  const int rows = int(x.dim(0)), cols = int(x.dim(1));
  Tensor y(x.shape(), what);
  host::launch("dst", "scale_columns", {size_t((cols + 7) / 8), size_t(rows)}, x, v, y, rows, cols);
  return y;
}

Dst Dst::create(bool bias, int group, uint64_t seed, const std::string& prefix) {
  Dst d;
  d.bias = bias;
  std::mt19937_64 rng(seed);
  d.w0 = uniform_param(prefix + "s_net.0.weight", group, {C, 128}, C, rng);
  d.b0 = uniform_param(prefix + "s_net.0.bias", group, {128}, C, rng);
  d.w2 = uniform_param(prefix + "s_net.2.weight", group, {128, 64}, 128, rng);
  d.b2 = uniform_param(prefix + "s_net.2.bias", group, {64}, 128, rng);
  d.w4 = uniform_param(prefix + "s_net.4.weight", group, {64, E}, 64, rng);
  d.b4 = uniform_param(prefix + "s_net.4.bias", group, {E}, 64, rng);
  d.fc_w = uniform_param(prefix + "s_fc.weight", group, {E * E, E * E}, E * E, rng);
  d.fc_b = uniform_param(prefix + "s_fc.bias", group, {E * E}, E * E, rng);
  d.unzip_w = uniform_param(prefix + "unzip.weight", group, {E, C}, E, rng);
  return d;
}

StyleCode Dst::style_code(const Tensor& s, StyleContext* ctx) const {
  if (!s.defined() || s.ndim() != 2 || s.dim(1) != C)
    throw Error("dst style_code: style features must be [L, 256] rows, got " +
                (s.defined() ? host::shape_str(s.shape()) : std::string("undefined")));
  if (s.dim(0) < 2) throw Error("dst style_code: a style needs at least 2 feature positions (an unbiased std)");
  const int L = int(s.dim(0));
  StyleCode code;
  code.mean = nn::column_mean(s);
  code.std = nn::column_std(s, code.mean, 1);
  const Tensor centred = subtract_row_vector(s, code.mean);
  const Tensor h1 = nn::relu_forward(nn::linear_forward(centred, w0.value, b0.value));
  const Tensor h2 = nn::relu_forward(nn::linear_forward(h1, w2.value, b2.value));
  const Tensor e = nn::linear_forward(h2, w4.value, b4.value);
  Tensor cov({1, E * E}, "style covariance");
  host::gemm(Trans::Yes, Trans::No, E, E, L, 1.0f / float(L), e.mem(), 0, E, e.mem(), 0, E, 0.0f, cov.mem(), 0, E);
  code.T = nn::linear_forward(cov, fc_w.value, fc_b.value).reshape({E, E});
  // A NaN or Inf in s, or features too large for float (the variance and the covariance hold their
  // squares), would leave a style code of NaN that silently turns every styled map NaN. Checked on the
  // small outputs; the input is read only to say which.
  if (nn::has_nonfinite(code.std) || nn::has_nonfinite(code.T)) {
    if (nn::has_nonfinite(s)) throw Error("dst style_code: the style features hold a NaN or an infinity");
    throw Error("dst style_code: the style's statistics overflow float (std or T is not finite): the style features "
                "are too large");
  }
  if (ctx) *ctx = {s, centred, h1, h2, e, cov, code};
  return code;
}

Tensor Dst::style_code_backward(const StyleContext& ctx, const Tensor& dT, const Tensor& dmean, const Tensor& dstd,
                                bool need_ds) {
  const int L = int(ctx.s.dim(0));
  Tensor dcentred;
  if (dT.defined()) {
    host::expect_shape(dT, {E, E}, "dst style_code_backward", "dT");
    const Tensor dcov = nn::linear_backward(ctx.cov, fc_w, &fc_b, dT.reshape({1, E * E}), true);
    // cov = E^T E / L  ->  dE = E (dcov + dcov^T) / L
    Tensor de({L, E}, "style embedding gradient");
    host::gemm(Trans::No, Trans::Yes, L, E, E, 1.0f / float(L), ctx.e.mem(), 0, E, dcov.mem(), 0, E, 0.0f, de.mem(), 0,
               E);
    host::gemm(Trans::No, Trans::No, L, E, E, 1.0f / float(L), ctx.e.mem(), 0, E, dcov.mem(), 0, E, 1.0f, de.mem(), 0,
               E);
    const Tensor dh2 = nn::relu_backward(ctx.h2, nn::linear_backward(ctx.h2, w4, &b4, de, true));
    const Tensor dh1 = nn::relu_backward(ctx.h1, nn::linear_backward(ctx.h1, w2, &b2, dh2, true));
    dcentred = nn::linear_backward(ctx.centred, w0, &b0, dh1, need_ds);
  }
  if (!need_ds) return Tensor();
  const bool has_c = dcentred.defined(), has_m = dmean.defined(), has_s = dstd.defined();
  if (has_m) host::expect_shape(dmean, {C}, "dst style_code_backward", "dmean");
  if (has_s) host::expect_shape(dstd, {C}, "dst style_code_backward", "dstd");
  const Tensor sum_dc = has_c ? nn::column_sum(dcentred) : ctx.code.mean;
  const Tensor& placeholder = ctx.code.mean;  // bound to absent arguments, never read
  Tensor ds(ctx.s.shape(), "style features gradient");
  host::launch("dst", "style_stats_backward", {size_t((C + 7) / 8), size_t(L)}, ctx.s, ctx.code.mean, ctx.code.std,
               has_c ? dcentred : ctx.s, sum_dc, has_m ? dmean : placeholder, has_s ? dstd : placeholder, ds, L, C,
               has_c ? 1 : 0, has_m ? 1 : 0, has_s ? 1 : 0);
  return ds;
}

Tensor Dst::apply(const Tensor& c, const Tensor& acc, const StyleCode& code, ApplyContext* ctx) const {
  if (!c.defined() || c.ndim() != 2 || c.dim(1) != E)
    throw Error("dst apply: c must be [R, 32], got " + (c.defined() ? host::shape_str(c.shape()) : std::string("undefined")));
  const int R = int(c.dim(0));
  if (R == 0) throw Error("dst apply: no rays");
  if (bias) host::expect_shape(acc, {R}, "dst apply", "acc");
  host::expect_shape(code.T, {E, E}, "dst apply", "T");
  Tensor M({E, C}, "dst M = T^T U");
  host::gemm(Trans::Yes, Trans::No, E, C, E, 1.0f, code.T.mem(), 0, E, unzip_w.value.mem(), 0, C, 0.0f, M.mem(), 0, C);
  Tensor Wp = scale_columns(M, code.std, "dst W' = M diag(std)");
  Tensor y({R, C}, "dst output");
  host::gemm(Trans::No, Trans::No, R, C, E, 1.0f, c.mem(), 0, E, Wp.mem(), 0, C, 0.0f, y.mem(), 0, C);
  if (bias) host::gemm(Trans::No, Trans::No, R, C, 1, 1.0f, acc.mem(), 0, 1, code.mean.mem(), 0, C, 1.0f, y.mem(), 0, C);
  // As in style_code: a NaN or Inf in, or an overflow (y grows as the cube of the style features' scale),
  // is an error here rather than a NaN map downstream.
  if (nn::has_nonfinite(y)) {
    if (nn::has_nonfinite(c) || (bias && nn::has_nonfinite(acc)))
      throw Error("dst apply: the content features c (or the opacities acc) hold a NaN or an infinity");
    throw Error("dst apply: the styled features overflow float: the style's T and std are too large");
  }
  if (ctx) *ctx = {c, acc, M, Wp, code};
  return y;
}

Dst::ApplyGrads Dst::apply_backward(const ApplyContext& ctx, const Tensor& dy, bool need_dc) {
  const int R = int(ctx.c.dim(0));
  host::expect_shape(dy, {R, C}, "dst apply_backward", "dy");
  ApplyGrads g;
  Tensor dWp({E, C}, "dst dW'");
  host::gemm(Trans::Yes, Trans::No, E, C, R, 1.0f, ctx.c.mem(), 0, E, dy.mem(), 0, C, 0.0f, dWp.mem(), 0, C);
  if (need_dc) {
    g.dc = Tensor({R, E}, "dst dc");
    host::gemm(Trans::No, Trans::Yes, R, E, C, 1.0f, dy.mem(), 0, C, ctx.Wp.mem(), 0, C, 0.0f, g.dc.mem(), 0, E);
  }
  if (bias) {
    g.dmean = Tensor({C}, "dst dmean");
    host::gemm(Trans::Yes, Trans::No, C, 1, R, 1.0f, dy.mem(), 0, C, ctx.acc.mem(), 0, 1, 0.0f, g.dmean.mem(), 0, 1);
  }
  g.dstd = nn::column_dot(ctx.M, dWp);
  const Tensor dM = scale_columns(dWp, ctx.code.std, "dst dM");
  host::gemm(Trans::No, Trans::No, E, C, E, 1.0f, ctx.code.T.mem(), 0, E, dM.mem(), 0, C, 1.0f,
             unzip_w.grad_buffer().mem(), 0, C);
  g.dT = Tensor({E, E}, "dst dT");
  host::gemm(Trans::No, Trans::Yes, E, E, C, 1.0f, unzip_w.value.mem(), 0, C, dM.mem(), 0, C, 0.0f, g.dT.mem(), 0, E);
  return g;
}

Tensor Dst::apply_per_point(const Tensor& c, const StyleCode& code) const {
  Tensor ones({c.dim(0)}, "per-point weights");
  ones.fill(1.0f);
  return apply(c, ones, code, nullptr);
}

void Dst::collect_params(std::vector<nn::Param*>& out) {
  for (nn::Param* p : {&w0, &b0, &w2, &b2, &w4, &b4, &fc_w, &fc_b, &unzip_w}) out.push_back(p);
}

}  // namespace stylerf::style
