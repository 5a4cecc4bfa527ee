// nn::VggTail: VGG-19 from relu3_1 to relu4_1 (conv3_2, conv3_3, conv3_4, 2x2 max pool, conv4_1, each conv
// followed by ReLU), frozen, as a module with a context (forward const; backward gives d input only).
//
// Why: AdaIN's pretrained decoder reads relu4_1 and StyleRF's maps are relu3_1. Putting this tail in front
// of it gives a decoder of relu3_1 maps that was trained, on a large set of photographs and paintings, to
// draw images whose VGG statistics match its input's, which is what the style stage's losses measure
// (docs/design.md, "Stage 3: style"; its runs: docs/experiments.md). The weights are the encoder's own: the tail of the network that encodes
// style images and measures the losses.
#pragma once
#include <vector>

#include "lib/nn/ops.hpp"
#include "lib/nn/vgg.hpp"

namespace stylerf::nn {

class VggTail {
 public:
  struct Ctx {
    std::vector<Tensor> inputs;  // each step's input
    std::vector<Tensor> outputs; // each step's output
    bool phases = false;         // forward's
  };
  VggTail() = default;
  explicit VggTail(const VggEncoder& vgg);  // copies (shares) conv3_2 .. conv4_1 of a loaded encoder
  bool loaded() const { return !convs_.empty(); }

  // x [N, 256, H, W] relu3_1 features, H and W even and >= 2 -> relu4_1 [N, 512, H/2, W/2].
  // phases: the pool's four grid offsets as batch blocks, [4N, 512, H/2, W/2] (maxpool2x2_phases_forward):
  // relu4_1 at every relu3_1 pixel, for a decoder that interleaves them (ConvStack::forward's phase_input).
  Tensor forward(const Tensor& x, Ctx* ctx = nullptr, bool phases = false) const;
  // d relu4_1 -> d relu3_1 (the weights are frozen: no parameter gradients).
  Tensor backward(const Ctx& ctx, const Tensor& dy) const;

 private:
  struct Conv {
    Tensor w, b;
    mutable ConvFilterCache filters;  // frozen weights: their Winograd transform is made once
  };
  std::vector<Conv> convs_;  // conv3_2, conv3_3, conv3_4, conv4_1; the pool sits before the last
  Padding pad_ = Padding::Reflect;
};

}  // namespace stylerf::nn
