#include "lib/train/reconstruction_loss.hpp"

#include "lib/nn/ops.hpp"
#include "lib/train/style_losses.hpp"

namespace stylerf::train {

ReconstructionLoss reconstruction_loss(nn::VggEncoder& vgg, const host::Tensor& rgb, const host::Tensor& target,
                                       const nn::VggFeatures& target_taps, float feature_weight,
                                       float style_weight) {
  const nn::VggFeatures out = vgg.forward(rgb, 4, true);
  ReconstructionLoss l;
  l.pixel_mse = nn::mse_forward(rgb, target).to_host()[0];
  l.feature_mse =
      double(nn::mse_forward(out[2], target_taps[2]).to_host()[0]) + nn::mse_forward(out[3], target_taps[3]).to_host()[0];
  nn::VggFeatures grads;
  grads[2] = nn::mse_backward(out[2], target_taps[2], feature_weight);
  grads[3] = nn::mse_backward(out[3], target_taps[3], feature_weight);
  if (style_weight > 0) {
    nn::VggFeatures style_grads;
    const StyleLossValues sv =
        style_losses(out, target_taps[3], target_taps, nullptr, StyleLossWeights{0.0f, style_weight}, &style_grads);
    l.style = sv.style;
    for (int t = 0; t < nn::VggFeatures::kCount; ++t) {
      if (!style_grads[t].defined()) continue;
      if (grads[t].defined())
        nn::axpby(1.0f, style_grads[t], 1.0f, grads[t]);
      else
        grads[t] = style_grads[t];
    }
  }
  l.drgb = vgg.backward(grads);
  vgg.release();
  nn::axpby(1.0f, nn::mse_backward(rgb, target, 1.0f), 1.0f, l.drgb);
  return l;
}

}  // namespace stylerf::train
