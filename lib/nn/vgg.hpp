// The frozen VGG-19 encoder up to relu4_1: the features AdaIN and StyleRF use (relu1_1 .. relu4_1), with a
// backward pass to the input image for the style and content losses.
//
// Two weight layouts are accepted, chosen from the keys in the file:
//  - AdaIN's vgg_normalised (keys "0.weight", "2.weight", ...): a 1x1 conv0 maps RGB in [0,1] to
//    BGR*255 - mean, then 3x3 convs with reflection padding;
//  - torchvision's VGG-19 (keys "features.0.weight", ...): expects ImageNet-normalised RGB, which we apply
//    as an equivalent fixed 1x1 conv, then 3x3 convs with zero padding.
// Either way forward() takes RGB in [0,1].
#pragma once
#include <string>
#include <vector>

#include "lib/nn/ops.hpp"

namespace stylerf::nn {

enum class VggVariant { AdainNormalised, Torchvision };

// The four taps; a tensor may be left undefined (not computed, or no gradient for it).
struct VggFeatures {
  static constexpr int kCount = 4;
  Tensor relu[kCount];  // relu1_1, relu2_1, relu3_1, relu4_1
  Tensor& operator[](int i) { return relu[i]; }
  const Tensor& operator[](int i) const { return relu[i]; }
};
const char* vgg_tap_name(int i);  // "relu1_1" .. "relu4_1"

class VggEncoder {
 public:
  VggEncoder() = default;
  // Loads a safetensors file (see weights.hpp for the default location). Errors name the file and what
  // is missing or mis-shaped; a missing file also names the set-up command.
  void load(const std::string& path);
  static VggEncoder load_default();  // weights_path(kVggWeightsFile)
  bool loaded() const { return !convs_.empty(); }
  VggVariant variant() const { return variant_; }
  const std::string& path() const { return path_; }

  // x: [N,3,H,W] RGB in [0,1], H and W multiples of 8 (three 2x2 poolings before relu4_1).
  // Computes the taps up to `deepest` (1 = relu1_1 ... 4 = relu4_1); deeper ones stay undefined.
  // With keep_for_backward the intermediate activations are kept until the next forward or release().
  VggFeatures forward(const Tensor& x, int deepest = 4, bool keep_for_backward = true);

  // d loss / d input for gradients at the taps of the last forward (any may be undefined, at least one
  // must be defined). The weights are frozen: no parameter gradients are computed.
  Tensor backward(const VggFeatures& grads);

  void release() { saved_.clear(); }

  // A loaded conv's weight [Cout, Cin, k, k] and bias (names "conv1_1" .. "conv4_1"), and the padding of
  // the 3x3 convs: for modules built from part of the network (nn::VggTail). An Error for other names.
  std::pair<Tensor, Tensor> conv_weights(const std::string& name) const;
  Padding padding() const { return pad_; }

 private:
  struct Conv {
    std::string name;
    Tensor w, b;
    ConvFilterCache filters;  // the weights are frozen: their Winograd transform is made once
  };
  // The program up to relu4_1: conv (+ relu) or 2x2 max pool; `tap` >= 0 marks a tap at the step output.
  struct Step {
    int conv = -1;  // index into convs_, or -1 for the pool
    bool relu = true;
    int tap = -1;
  };

  std::string path_;
  VggVariant variant_ = VggVariant::AdainNormalised;
  Padding pad_ = Padding::Reflect;
  // convs_[0] is the 1x1 input conv (no relu): RGB in [0,1] -> what the network expects; then
  // conv1_1 .. conv4_1.
  std::vector<Conv> convs_;
  std::vector<Step> steps_;
  std::vector<Tensor> saved_;  // saved_[0] = the input, saved_[i + 1] = output of steps_[i]
  int saved_deepest_ = 0;
};

}  // namespace stylerf::nn
