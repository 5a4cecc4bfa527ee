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
  if (style_weight > 0)  // fills all four taps' gradients (its content term, at weight 0, adds nothing)
    l.style = style_losses(out, target_taps[3], target_taps, nullptr, StyleLossWeights{0.0f, style_weight}, &grads).style;
  for (int t : {2, 3}) {
    const host::Tensor g = nn::mse_backward(out[t], target_taps[t], feature_weight);
    if (grads[t].defined())
      nn::axpby(1.0f, g, 1.0f, grads[t]);
    else
      grads[t] = g;
  }
  l.drgb = vgg.backward(grads);
  vgg.release();
  nn::axpby(1.0f, nn::mse_backward(rgb, target, 1.0f), 1.0f, l.drgb);
  return l;
}

}  // namespace stylerf::train
