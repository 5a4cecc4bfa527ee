// nn::ConvStack: a chain of 3x3 stride-1 convs, ReLU after every conv but the last, and optionally a
// nearest x2 upsampling after a conv's ReLU. Every decoder StyleRF uses is one (lib/nn/decoder.hpp:
// AdaIN's pretrained decoder, the PlainDecoder of the paper profile, the fast profile's decoder).
//
// Module convention (nn/module.hpp): forward(x, ctx) keeps in ctx what backward needs (nullptr:
// inference); backward(ctx, dy) ACCUMULATES into every conv's weight and bias Param and returns dx.
// forward is const, so one stack can serve several forwards in flight (each with its own Ctx).
//
// Stack files are the state dict of the equivalent PyTorch nn.Sequential, which is what AdaIN's
// decoder.pth is: keys "<module index>.weight" / ".bias", the indices following from the architecture.
//   reflect padding: pad, conv, relu, [upsample], pad, conv, ...  first conv is module 1, the next conv
//                    3 modules later, or 4 after an upsampling (AdaIN: 1, 5, 8, 11, 14, 18, ...);
//   zero padding:    conv(padding=1), relu, [upsample], conv, ...  first conv is module 0, then +2 / +3.
// The file's metadata "padding" says which ("reflect" when absent: AdaIN's file has no metadata), and a
// loaded file's upsamplings are read back from the index gaps. Parameters are named
// "<name_prefix><module index>.weight" / ".bias"; the indices are always renumbered from the first conv,
// so a stack built from a spec and one loaded from a file of the same architecture share names (and
// Module::load can fill either from the other's checkpoint).
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "lib/nn/module.hpp"
#include "lib/nn/ops.hpp"

namespace stylerf::nn {

struct ConvStackSpec {
  std::vector<int> channels;         // c0 -> c1 -> ... -> cn: n convs, n >= 1
  std::vector<bool> upsample_after;  // n entries (or empty: none): nearest x2 after conv i's ReLU
  Padding pad = Padding::Reflect;
  std::string name_prefix;           // parameter names "<prefix><module index>.weight"
  int group = 0;                     // optimiser group (nn::Adam) of every parameter

  // Same architecture (channels, upsamplings, padding); names and group aside.
  bool same_architecture(const ConvStackSpec& o) const;
  std::string describe() const;      // "reflect 256-256-...-3, x2 after convs 4, 6" (1-based)
};

class ConvStack : public Module {
 public:
  struct Layer {
    int index = 0;         // module index in the equivalent nn.Sequential (file key "<index>.weight")
    Param w, b;            // [Cout, Cin, 3, 3], [Cout]
    bool relu = true;      // false only for the last conv
    bool upsample = false; // nearest x2 after the ReLU
  };
  // What backward needs, filled by forward.
  struct Ctx {
    std::vector<Tensor> inputs;    // each conv's input
    std::vector<Tensor> relu_out;  // each conv's ReLU output (undefined for the last conv)
    bool phase_input = false;      // forward's
    // Each conv's Winograd filter transform, made by forward and reused by backward's dX (the weights
    // cannot change in between). Unused while the stack is frozen: its own caches serve both.
    mutable std::vector<ConvFilterCache> filters;
  };

  ConvStack() = default;
  // He-normal weights (std sqrt(2 / fan_in)), zero biases, drawn from `seed`. Errors name what is wrong
  // with the spec.
  ConvStack(const ConvStackSpec& spec, uint64_t seed);
  // A stack file (see above). Errors name the file and what is wrong (no conv keys, index gaps that are
  // not (relu, pad) or (relu, upsample, pad), channels that do not chain, missing biases).
  static ConvStack from_file(const std::string& path, const std::string& name_prefix = "", int group = 0);
  // Same keys as from_file reads (AdaIN's keys for AdaIN's layout), written atomically.
  void save_file(const std::string& path) const;

  // Redraws every weight (He normal) and zeroes every bias, from `seed`; the architecture stays.
  void init_he(uint64_t seed);
  // The stack made of layers [first, end) of this one: weights copied (not shared), module indices
  // renumbered, parameters renamed under name_prefix. The last layer stays without a ReLU.
  ConvStack tail(int first, const std::string& name_prefix, int group) const;

  bool empty() const { return layers_.empty(); }
  ConvStackSpec spec() const;  // architecture, prefix and group (build an identical stack from it)
  int in_channels() const;
  int out_channels() const;
  int upsamplings() const;     // the output is 2^upsamplings() times the input's size
  Padding padding() const { return pad_; }
  const std::string& name_prefix() const { return prefix_; }
  const std::vector<Layer>& layers() const { return layers_; }

  // x [N, Cin, H, W] -> [N, Cout, H * 2^u, W * 2^u]. Checks every layer's input size before launching
  // anything: a reflect-padded conv needs H, W >= 2 (PyTorch's ReflectionPad2d(1) refuses a 1-pixel
  // side too), so a 1x1 input is an Error naming the layer; zero padding takes any size.
  // phase_input: x holds the four grid phases of one map as batch blocks ([4N, Cin, H, W], from
  // maxpool2x2_phases_forward and convs), and the first upsampling interleaves them instead
  // (phase_interleave_forward): the output is [N, Cout, H * 2^u, W * 2^u]. An Error when the stack has no
  // upsampling or the batch is not a multiple of 4.
  Tensor forward(const Tensor& x, Ctx* ctx = nullptr, bool phase_input = false) const;
  // dy of forward's output -> dx (undefined when need_dx is false: the first conv skips its col2im).
  // Adds dW and db of every conv into the Params' grads.
  Tensor backward(const Ctx& ctx, const Tensor& dy, bool need_dx = true);

  // Hands out the weights to be written (an optimiser, Module::load): it unfreezes the stack (below).
  void collect_params(std::vector<Param*>& out) override;

  // A frozen stack reuses each conv's Winograd filter transform (nn::ConvFilterCache) in every forward and
  // backward instead of making it per call: a third of a small stylised frame's device time. For
  // inference: the weights must not change while frozen. Every writable path to them (collect_params, so
  // an optimiser, Module::load, init_he) unfreezes the stack first, so a stack that is trained or loaded
  // after freeze() is never served a stale transform; call freeze() again once done.
  void freeze();
  void unfreeze();
  bool frozen() const { return frozen_; }

 private:
  std::string where() const;  // "ConvStack 'decoder.'" for errors
  void name_params();         // from prefix_ and each layer's index
  ConvFilterCache* filters_for(size_t layer, const Ctx* ctx) const;

  std::vector<Layer> layers_;
  Padding pad_ = Padding::Reflect;
  std::string prefix_;
  int group_ = 0;
  bool frozen_ = false;
  // One per layer while frozen; mutable because forward is const (a cache, not state a caller sees).
  mutable std::vector<ConvFilterCache> frozen_filters_;
};

}  // namespace stylerf::nn
