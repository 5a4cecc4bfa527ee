// AdaIN's decoder: relu4_1 features (512 channels) back to an RGB image, with forward and backward.
//
// A chain of 3x3 reflect-padded convs, ReLU after every conv but the last, and a nearest x2 upsampling
// after some of them. The chain is read from the weights file rather than hard-coded: AdaIN's decoder is
// an nn.Sequential whose keys are "<module index>.weight"; between two convs the modules are
// (relu, pad) -> index gap 3, or (relu, upsample, pad) -> gap 4, which is how the upsamplings are found.
// The parameters are trainable (StyleRF fine-tunes the decoder): backward fills dw/db of every layer.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "lib/nn/ops.hpp"

namespace stylerf::nn {

class AdainDecoder {
 public:
  struct Layer {
    std::string key;  // module index in the original Sequential ("1", "5", ...), used when saving
    Tensor w, b;      // [Cout,Cin,3,3], [Cout]
    Tensor dw, db;    // gradients of the last backward (overwritten, not accumulated)
    bool relu = true;
    bool upsample = false;  // nearest x2 after the relu
  };

  AdainDecoder() = default;
  // Errors name the file and what is wrong (missing keys, gaps we do not understand, channel mismatch).
  void load(const std::string& path);
  static AdainDecoder load_default();  // weights_path(kDecoderWeightsFile)
  void save(const std::string& path) const;  // same keys as the loaded file, atomic
  bool loaded() const { return !layers_.empty(); }

  // Re-initialises every weight in place (He normal: std sqrt(2 / fan_in), zero bias) with a fixed seed;
  // the architecture stays. For baselines and from-scratch training.
  void init_he(uint64_t seed);

  int in_channels() const;   // 512 for AdaIN
  int upsamplings() const;   // 3 for AdaIN: output is 8x the input size
  std::vector<Layer>& layers() { return layers_; }
  const std::vector<Layer>& layers() const { return layers_; }

  // x [N,Cin,h,w] -> [N,3,h*2^u,w*2^u]. With keep_for_backward the activations are kept for backward().
  Tensor forward(const Tensor& x, bool keep_for_backward = true);
  // dy of the output -> dx (undefined when need_dx is false); sets every layer's dw and db.
  Tensor backward(const Tensor& dy, bool need_dx = true);
  void release() { inputs_.clear(), relu_out_.clear(); }

 private:
  std::vector<Layer> layers_;
  std::vector<Tensor> inputs_;    // conv inputs
  std::vector<Tensor> relu_out_;  // relu outputs (relu backward uses them)
};

}  // namespace stylerf::nn
