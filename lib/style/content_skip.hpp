// The content skip: beside DST's path through SICT's 32-channel embedding, the composited features
// themselves, each of the 256 channels normalised with SICT's statistics and moved to the style's channel
// statistics (AdaIN at relu3_1, per channel), scaled by a trained gain:
//   y += (Z B - acc mean_s) diag(g * std / sqrt(var_s + eps))
// Z [R, F]: per ray its kept samples' features composited, as components of a basis B [F, 256] (the feature
// field's, rendered maps) or as the features themselves (B = I, 2D maps); acc [R]: their kept opacity;
// mean_s, var_s: the statistics SICT normalises with (its running statistics at inference); std: the style's
// relu3_1 channel std (DST's code); g [256]: the gain, 1 at the start.
// Why: DST's content reaches the decoder through 32 channels (SICT's q/k/v embedding, T, unzip), which keeps
// the silhouette and paints the parts inside over (docs/experiments.md, "Where the structure goes"); the
// per-channel path keeps each channel's spatial detail. It is linear in (Z, acc) as DST is in (c, acc), so it
// composites along rays, averages over a block's sub-rays, blends between styles and splits by region masks
// exactly as DST does, and with SICT's running statistics a point's contribution does not depend on which
// other points were sampled (sampling-invariant, like SICT).
// Parameter "<prefix>gain" [256] (group kGroupStylizer of the style model).
#pragma once
#include <string>

#include "host/tensor.hpp"
#include "lib/nn/module.hpp"

namespace stylerf::style {

using host::Tensor;

class ContentSkip : public nn::Module {
 public:
  static constexpr int kChannels = 256;
  static constexpr float kEps = 1e-5f;  // SICT's
  nn::Param gain;

  static ContentSkip create(int group, const std::string& prefix = "style.skip.");

  // Where Z lies: columns [col, col + F) of z's rows (F = the basis's rows).
  struct Input {
    Tensor z;
    int col = 0;
    Tensor acc;          // [R]
    Tensor basis;        // [F, 256]; undefined: the identity (z is then the [R, 256] features themselves)
    Tensor mean, var;    // [256]: the statistics the features are normalised with
  };
  struct Context {
    Input in;
    Tensor scale;  // [256]: g * std / sqrt(var + eps)
    Tensor inv;    // [256]: 1 / sqrt(var + eps)
    Tensor std;    // [256]: the style's
  };
  // y [R, 256] += the skip of `in` under the style's channel std [256].
  void forward_add(const Input& in, const Tensor& style_std, Tensor& y, Context* ctx) const;
  // Accumulates into gain; returns d std [256] (the style's std gets a gradient through the scale).
  Tensor backward(const Context& ctx, const Tensor& dy);

  void collect_params(std::vector<nn::Param*>& out) override { out.push_back(&gain); }
};

}  // namespace stylerf::style
