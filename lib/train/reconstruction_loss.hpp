// Stage 2's decoder loss, shared by the feature stage's patch steps and the style stage's decoder warm-up:
// pixel MSE + feature_weight x (relu3_1 MSE + relu4_1 MSE), VGG of the decoded image against the target's.
#pragma once
#include "host/tensor.hpp"
#include "lib/nn/vgg.hpp"

namespace stylerf::train {

struct ReconstructionLoss {
  double pixel_mse = 0;    // mean((rgb - target)^2)
  double feature_mse = 0;  // relu3_1 MSE + relu4_1 MSE, unweighted
  host::Tensor drgb;       // d loss / d rgb
};

// rgb, target [1, 3, H, W]; target_taps = vgg.forward(target, 4, ...). Runs VGG forward and backward on rgb
// (its activations are released before returning). feature_weight 0 is pixel MSE alone: VGG is not run,
// target_taps are not read (may be empty) and feature_mse is 0.
ReconstructionLoss reconstruction_loss(nn::VggEncoder& vgg, const host::Tensor& rgb, const host::Tensor& target,
                                       const nn::VggFeatures& target_taps, float feature_weight);

}  // namespace stylerf::train
