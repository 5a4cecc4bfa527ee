// Stage 2's decoder loss, shared by the feature stage's patch steps and the style stage's decoder warm-up:
// pixel MSE + feature_weight x (relu3_1 MSE + relu4_1 MSE), VGG of the decoded image against the target's;
// optionally + style_weight x the style stage's style term (lib/train/style_losses.hpp: MSE of channel means
// and stds at relu1_1..relu4_1) of the decoded image against the target. The style term asks for the fine
// texture that a pixel and feature MSE let a decoder blur (a blurred image has near-right features and the
// wrong statistics); both terms are minimal at a perfect inversion, so they do not pull against each other.
#pragma once
#include "host/tensor.hpp"
#include "lib/nn/vgg.hpp"

namespace stylerf::train {

struct ReconstructionLoss {
  double pixel_mse = 0;    // mean((rgb - target)^2)
  double feature_mse = 0;  // relu3_1 MSE + relu4_1 MSE, unweighted
  double style = 0;        // style_weight x the style term (0 when style_weight is 0)
  host::Tensor drgb;       // d loss / d rgb
};

// rgb, target [1, 3, H, W]; target_taps = vgg.forward(target, 4, ...). Runs VGG forward and backward on rgb
// (its activations are released before returning).
ReconstructionLoss reconstruction_loss(nn::VggEncoder& vgg, const host::Tensor& rgb, const host::Tensor& target,
                                       const nn::VggFeatures& target_taps, float feature_weight,
                                       float style_weight = 0.0f);

}  // namespace stylerf::train
