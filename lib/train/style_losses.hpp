// The style stage's losses (StyleRF's train_style, docs/design.md):
//   content = MSE of relu4_1 between VGG of the stylised image and of the true image, x content_weight (the
//             paper's 1; the fast recipe's 3, train::style_recipe);
//   style   = sum over relu1_1 .. relu4_1 of the AdaIN style loss (MSE of channel means + MSE of channel
//             stds) between the stylised image and the style image, x style_weight (20).
// On scenes with a background (images with alpha) both are masked by the rendered opacity: the opacity
// map is bilinearly resized to each tap's size and positions with opacity >= 1e-5 are kept (the
// authors' rule); the content MSE averages over kept positions, the statistics are those of kept positions.
#pragma once
#include <array>
#include <vector>

#include "host/tensor.hpp"
#include "lib/nn/ops.hpp"
#include "lib/nn/vgg.hpp"

namespace stylerf::train {

using host::Tensor;

// Kept positions of each VGG tap (I32 [M] row-major indices), from an opacity map.
struct OpacityMask {
  std::array<Tensor, nn::VggFeatures::kCount> idx;
  std::array<int, nn::VggFeatures::kCount> count{};
  bool empty() const { return count[nn::VggFeatures::kCount - 1] == 0; }
};
// acc [h][w] (row-major); tap t has size (H >> t) x (W >> t) for an H x W image.
OpacityMask opacity_mask(const std::vector<float>& acc, int h, int w, int H, int W);

// [1, C, H, W] -> [1, C, 1, M] at the kept positions, and its transpose.
Tensor gather_positions(const Tensor& x, const Tensor& idx);
Tensor scatter_positions(const Tensor& d, const Tensor& idx, int H, int W);

struct StyleLossWeights {
  float content = 1.0f, style = 20.0f;
};
struct StyleLossValues {
  double content = 0, style = 0;  // weighted
  std::array<double, nn::VggFeatures::kCount> style_tap{};  // style's terms per tap (relu1_1 .. relu4_1), weighted
  double total() const { return content + style; }
};
// The style image's side of the style loss: each tap's channel statistics (nn::style_target), measured once
// per style image (a 256 px image's taps are 30 MB; these, a few KB).
using StyleTargets = std::array<nn::StyleTarget, nn::VggFeatures::kCount>;
StyleTargets style_targets(const nn::VggFeatures& style);

// out: taps of the stylised image; content41: relu4_1 of the true image; style: taps of the style image.
// mask null: no masking. grads non-null: filled with d loss / d tap (for VggEncoder::backward).
StyleLossValues style_losses(const nn::VggFeatures& out, const Tensor& content41, const nn::VggFeatures& style,
                             const OpacityMask* mask, const StyleLossWeights& w, nn::VggFeatures* grads);
// The same, against the style's targets (style_losses(out, c, style_targets(style), ...) is bit-identical).
StyleLossValues style_losses(const nn::VggFeatures& out, const Tensor& content41, const StyleTargets& style,
                             const OpacityMask* mask, const StyleLossWeights& w, nn::VggFeatures* grads);

}  // namespace stylerf::train
