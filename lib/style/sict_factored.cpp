// SICT on the feature field's components (Sict::forward_factored and its backward).
//
// In stage 3 every kept sample's features are x = f B: f [K, F] are the VM grid's components at the point
// and B [F, 256] the field's basis, frozen and without a bias. SICT's first two steps are linear in x:
//   normed = (x - m) s                 (s_c = rsqrt(v_c + eps), per channel c)
//   qkv    = normed W + b
// so with centred components f~ = f - mean(f) (batch statistics: m = mean(f) B, hence x - m = f~ B):
//   qkv = f~ (B diag(s) W) + b
// and with running statistics (m a constant that need not lie in B's row space):
//   qkv = f (B diag(s) W) + (b - (m s) W).
// The batch variance of x comes from f's centred covariance, v_c = B_c^T Cov(f) B_c (biased, as forward
// uses). Nothing of width 256 per point is formed: the [K, 256] features, their normalised copy and the
// K x 256 x 96 GEMM give way to K x F x 96 (F = 144 on Blender scenes, 72 on LLFF). On an H100 those
// tensors were 3.2 GB each at the paper's 3.1M kept samples per step.
//
// The weight gradient: normed = f~ B_s - shift with B_s = B diag(s) (shift = m s with running statistics),
// so dW = normed^T dqkv = B_s^T (f~^T dqkv) - shift (x) sum_rows(dqkv). No dx: the field is frozen in stage 3.
//
// Centring first keeps the cancellation where the unfactored op has it (x - m per element), not in
// E[f f^T] - mean mean^T; tests/test_sict_factored.cpp checks components with a mean of 1e3 and a spread of 1.
#include <string>

#include "host/error.hpp"
#include "host/gemm.hpp"
#include "lib/nn/columns.hpp"
#include "lib/nn/linear.hpp"
#include "lib/nn/ops.hpp"
#include "lib/style/sict.hpp"

namespace stylerf::style {

using host::Error;
using host::Trans;

namespace {

// rows - mean (per column), exactly as a float subtraction: a copy plus the bias add of -mean.
Tensor centred_rows(const Tensor& rows, const Tensor& mean) {
  Tensor neg = Tensor::zeros(mean.shape(), "sict -mean(components)");
  nn::axpby(-1.0f, mean, 1.0f, neg);
  Tensor out = rows.clone();
  nn::linear_add_bias(out, neg);
  return out;
}

// [1, n] row views of a vector, for GEMMs with one row.
Tensor as_row(const Tensor& v) { return v.reshape({1, v.numel()}); }

}  // namespace

Tensor Sict::forward_factored(const Tensor& comps, const Tensor& basis, bool training, Context* ctx) const {
  if (!comps.defined() || comps.ndim() != 2 || comps.dim(0) == 0)
    throw Error("sict forward_factored: components must be [K, F] with K > 0, got " +
                (comps.defined() ? host::shape_str(comps.shape()) : std::string("undefined")));
  const int64_t F = comps.dim(1);
  host::expect_shape(basis, {F, kChannels}, "sict forward_factored", "basis");
  Tensor rows = comps, scaled = basis, shift, mean, var;
  bool batch = false;
  if (mode != SictMode::None) {
    batch = (mode == SictMode::VanillaIn) || training;
    if (batch) {
      const Tensor comp_mean = nn::column_mean(comps);
      rows = centred_rows(comps, comp_mean);
      Tensor cov({F, F}, "sict component covariance");
      host::matmul(rows, Trans::Yes, rows, Trans::No, cov, 1.0f / float(comps.dim(0)));
      mean = nn::linear_forward(as_row(comp_mean), basis, Tensor()).reshape({kChannels});
      var = nn::column_dot(basis, nn::linear_forward(cov, basis, Tensor()));
    } else {
      mean = running_mean.value;
      var = running_var.value;
    }
    // B diag(s) and m s with the very expression point_norm_forward normalises x with.
    const Tensor zero = Tensor::zeros({kChannels}, "sict zero mean");
    scaled = point_norm_forward(basis, zero, var, kEps);
    if (!batch) shift = point_norm_forward(as_row(mean), zero, var, kEps).reshape({kChannels});
  }
  const Tensor w_eff = nn::linear_forward(scaled, qkv_w.value, Tensor());  // [F, 96]
  Tensor b_eff = qkv_b.value;
  if (shift.defined()) {
    Tensor b_row = qkv_b.value.clone().reshape({1, 3 * kEmbed});
    host::matmul(as_row(shift), Trans::No, qkv_w.value, Trans::No, b_row, -1.0f, 1.0f);
    b_eff = b_row.reshape({3 * kEmbed});
  }
  Tensor qkv = nn::linear_forward(rows, w_eff, b_eff);
  Tensor out = channel_attention_forward(qkv);
  if (ctx) {
    *ctx = Context{};
    ctx->mean = mean;
    ctx->var = var;
    ctx->batch_stats = batch;
    ctx->qkv = qkv;
    ctx->points = comps.dim(0);
    ctx->rows = rows;
    ctx->scaled_basis = scaled;
    ctx->shift = shift;
  }
  return out;
}

// Sict::backward for a forward_factored context: the weight and bias gradients only.
void sict_factored_backward(const Sict::Context& ctx, const Tensor& dqkv, nn::Param& qkv_w, nn::Param& qkv_b) {
  const int64_t F = ctx.rows.dim(1), Q = dqkv.dim(1);
  Tensor g({F, Q}, "sict components^T dqkv");
  host::matmul(ctx.rows, Trans::Yes, dqkv, Trans::No, g);
  Tensor& dw = qkv_w.grad_buffer();
  Tensor& db = qkv_b.grad_buffer();
  host::matmul(ctx.scaled_basis, Trans::Yes, g, Trans::No, dw, 1.0f, 1.0f);
  if (!ctx.shift.defined()) {
    nn::column_sum_into(dqkv, db, true);
    return;
  }
  const Tensor sum = nn::column_sum(dqkv);
  nn::axpby(1.0f, sum, 1.0f, db);
  host::matmul(ctx.shift.reshape({ctx.shift.numel(), 1}), Trans::No, as_row(sum), Trans::No, dw, -1.0f, 1.0f);
}

}  // namespace stylerf::style
