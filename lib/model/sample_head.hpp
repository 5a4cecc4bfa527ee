// What the ray pipeline asks of a value head: C values for each kept sample, from its normalised position
// (and, only for heads that say so, the view direction). Heads: RGB (stage 1, lib/model/rgb_head.hpp),
// VGG features (stage 2), SICT (stage 3). A head is a module (lib/nn/module.hpp): backward accumulates
// into its parameters' gradients.
#pragma once
#include <memory>

#include "host/tensor.hpp"
#include "lib/nn/module.hpp"

namespace stylerf::model {

using host::Tensor;

class SampleHead : public nn::Module {
 public:
  // What forward keeps for backward; each head derives its own.
  struct Context {
    virtual ~Context() = default;
  };
  virtual int channels() const = 0;
  virtual bool wants_view_dirs() const { return false; }
  // pos [K,3] normalised to the box, dirs [K,3] unit view directions (defined only when wants_view_dirs).
  // ctx null: inference (nothing kept).
  virtual Tensor forward(const Tensor& pos, const Tensor& dirs, std::unique_ptr<Context>* ctx) const = 0;
  // dvalues [K, C]; adds to the parameters' gradients.
  virtual void backward(const Context& ctx, const Tensor& dvalues) = 0;
};

}  // namespace stylerf::model
