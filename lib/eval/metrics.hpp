// Image quality metrics on host images, as the NeRF papers report them.
//
// PSNR = -10 log10(MSE) for values in [0,1] (peak 1), MSE over every pixel and channel.
// SSIM as in the NeRF / mip-NeRF evaluation code (Wang et al. 2004 with the usual constants): an 11x11
// Gaussian window with sigma 1.5 (separable), K1 = 0.01, K2 = 0.03, data range 1, "valid" filtering (no
// padding: the map is (H-10) x (W-10)), variances clamped at 0, and the mean of the SSIM map over all
// positions and channels. Computed in double.
#pragma once
#include <vector>

#include "lib/io/image.hpp"

namespace stylerf::eval {

double mse(const std::vector<float>& a, const std::vector<float>& b);
// +infinity for identical images (MSE 0).
double psnr_from_mse(double mse);
double psnr(const std::vector<float>& a, const std::vector<float>& b);
// Interleaved [H*W][3] -> planar [3][H*W] (what ssim() takes).
std::vector<float> interleaved_to_planar(const std::vector<float>& hwc, int width, int height);

struct SsimOptions {
  int window = 11;
  double sigma = 1.5, k1 = 0.01, k2 = 0.03, data_range = 1.0;
};

// Planar images [channels][height][width]; both at least window x window.
double ssim(const std::vector<float>& a, const std::vector<float>& b, int width, int height, int channels,
            const SsimOptions& opt = {});
double ssim(const io::Image& a, const io::Image& b, const SsimOptions& opt = {});

}  // namespace stylerf::eval
