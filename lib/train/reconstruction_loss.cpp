#include "lib/train/reconstruction_loss.hpp"

#include "lib/nn/ops.hpp"

namespace stylerf::train {

ReconstructionLoss reconstruction_loss(nn::VggEncoder& vgg, const host::Tensor& rgb, const host::Tensor& target,
                                       const nn::VggFeatures& target_taps, float feature_weight) {
  ReconstructionLoss l;
  l.pixel_mse = nn::mse_forward(rgb, target).to_host()[0];
  if (feature_weight == 0.0f) {  // pixels only: no VGG pass at all (it is ~45% of a feature-stage patch step)
    l.drgb = nn::mse_backward(rgb, target, 1.0f);
    return l;
  }
  const nn::VggFeatures out = vgg.forward(rgb, 4, true);
  l.feature_mse =
      double(nn::mse_forward(out[2], target_taps[2]).to_host()[0]) + nn::mse_forward(out[3], target_taps[3]).to_host()[0];
  nn::VggFeatures grads;
  grads[2] = nn::mse_backward(out[2], target_taps[2], feature_weight);
  grads[3] = nn::mse_backward(out[3], target_taps[3], feature_weight);
  l.drgb = vgg.backward(grads);
  vgg.release();
  nn::axpby(1.0f, nn::mse_backward(rgb, target, 1.0f), 1.0f, l.drgb);
  return l;
}

}  // namespace stylerf::train
