// Deferred style transformation (StyleRF Sec. 3.3), applied to the rendered 2D map of SICT outputs rather
// than to every 3D sample (kernels/dst.cl; products through host/gemm.hpp):
//   style branch: s = the style image's relu3_1 features as rows [L, 256] -> mean and std per channel
//     (std UNBIASED, no eps: the authors') -> s - mean -> 1x1 convs 256 -> 128 -> ReLU -> 64 -> ReLU -> 32
//     -> covariance E^T E / L (not re-centred; 32 x 32) -> linear 1024 -> 1024 -> T (32 x 32);
//   applied to a ray's composited SICT output c (32) and its opacity w_r:
//     y = unzip(T c) * std + w_r * mean        (unzip: 1x1 conv 32 -> 256 without bias)
//   which is y = c (T^T U) diag(std) + w_r mean: one [R, 32] x [32, 256] GEMM and a rank-1 GEMM per map.
// Since it is linear in c and the bias scales with w_r, it equals compositing the per-point transform
// sum_i w_i (unzip(T c_i) * std + mean): the deferred-vs-per-point test (tests/test_style_model.cpp).
//
// The ablation "no bias" (Fig. 7 b) drops w_r * mean.
// Parameters "<prefix>s_net.{0,2,4}.weight" [in, out] and ".bias", "<prefix>s_fc.weight" [1024, 1024]
// ([in, out]) and ".bias", "<prefix>unzip.weight" [32, 256] ([in, out]). PyTorch stores the transposes.
#pragma once
#include <cstdint>
#include <string>

#include "host/tensor.hpp"
#include "lib/nn/module.hpp"

namespace stylerf::style {

using host::Tensor;

// What a style image contributes: the channel statistics of its relu3_1 features and T.
struct StyleCode {
  Tensor mean, std;  // [256]
  Tensor T;          // [32, 32]
  // The style's relu4_1 channel statistics, [1, 512] each (std with the biased variance + 1e-5, as
  // nn::channel_stats_forward): the vgg-adain-relu4 style decoder re-normalises its relu4_1 input to them
  // (lib/model/style_model.hpp). DST reads relu3_1's only. Undefined where not computed.
  Tensor deep_mean, deep_std;
  // The relu4_1 channel statistics of one scene's maps under this style, [1, 512] each (pooled over a few
  // training views: model::StyleModel::attach_scene_stats). Where defined, the vgg-adain-relu4 decoder
  // re-normalises a frame from these rather than from the frame's own statistics, so every frame of the
  // scene gets the same per-channel map. Undefined for a code not yet tied to a scene.
  Tensor scene_mean, scene_std;
  // The range of those maps' values per channel, [1, 512] each: a frame's relu4_1 is clamped to it before the
  // re-normalisation. A channel the pooled views never saw vary has std = sqrt(1e-5); were it to fire in a
  // novel view, (x - mean) / std would be thousands (horns 1/8: z = 2799, painted as a dark ball).
  Tensor scene_lo, scene_hi;
};

// x [rows, cols] times v [cols] column by column (kernels/dst.cl): DST's M diag(std), the content skip's weights.
Tensor scale_columns(const Tensor& x, const Tensor& v, const char* what);

class Dst : public nn::Module {
 public:
  static constexpr int kChannels = 256, kEmbed = 32;
  bool bias = true;  // false: the "no bias" ablation
  nn::Param w0, b0, w2, b2, w4, b4, fc_w, fc_b, unzip_w;

  // PyTorch's default init (U(+-1/sqrt(fan_in)) for weights and biases), seeded.
  static Dst create(bool bias, int group, uint64_t seed, const std::string& prefix = "stylizer.dst.");

  struct StyleContext {
    Tensor s, centred, h1, h2, e, cov;  // rows [L, .]; cov [1, 1024]
    StyleCode code;
  };
  // s [L, 256] (L >= 2 positions). ctx null: inference.
  // A constant channel has std exactly 0 (its styled channel is w_r * mean) and no std gradient (the
  // subgradient 0, kernels/dst.cl). Under the flush (docs/design.md) a channel whose deviations from its
  // mean are all below ~1e-19 has squares below FLT_MIN and so std 0 too. Throws an Error naming DST when
  // s holds a NaN or Inf, or when the std or T overflow float (features of ~1e18 and above).
  StyleCode style_code(const Tensor& s, StyleContext* ctx) const;
  // Gradients of T, mean, std (any undefined = none); accumulates into the style branch's parameters;
  // returns ds [L, 256] when need_ds.
  Tensor style_code_backward(const StyleContext& ctx, const Tensor& dT, const Tensor& dmean, const Tensor& dstd,
                             bool need_ds);

  struct ApplyContext {
    Tensor c, acc, M, Wp;  // M = T^T U [32, 256], Wp = M diag(std)
    StyleCode code;
  };
  // c [R, 32], acc [R] -> [R, 256]. Throws an Error naming DST when c or acc hold a NaN or Inf, or when the
  // output overflows float (it grows as the cube of the style features' scale: ~1e14 and above).
  Tensor apply(const Tensor& c, const Tensor& acc, const StyleCode& code, ApplyContext* ctx) const;
  struct ApplyGrads {
    Tensor dc, dT, dmean, dstd;  // dc only when asked for; dmean undefined without the bias
  };
  // Accumulates into unzip_w. (No gradient for acc: it comes from the frozen geometry.)
  ApplyGrads apply_backward(const ApplyContext& ctx, const Tensor& dy, bool need_dc);
  // The transform of single points (per-point order, for the deferred-vs-per-point proof): the same as
  // apply() with every weight 1.
  Tensor apply_per_point(const Tensor& c, const StyleCode& code) const;

  void collect_params(std::vector<nn::Param*>& out) override;
};

}  // namespace stylerf::style
