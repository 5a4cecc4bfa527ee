// The module convention every trainable part of StyleRF follows (grids, heads, decoders, stylizers):
//   - parameters are named (unique within a model, e.g. "decoder.conv3.w") and belong to an optimiser
//     group (an index into nn::Adam's groups: grids, networks, ...);
//   - forward(x, ctx) fills a context with what backward needs (nullptr: inference, nothing kept);
//   - backward(ctx, dy) ACCUMULATES into each parameter's grad (so several losses, or several chunks of
//     rays, add up) and returns the gradient of the input; zero_grad() starts a step;
//   - buffers are non-trainable state that checkpoints must keep (running statistics);
//   - save/load go through a checkpoint under a prefix, by name, shapes checked.
#pragma once
#include <string>
#include <vector>

#include "host/tensor.hpp"

namespace stylerf::io {
struct Checkpoint;
}

namespace stylerf::nn {

using host::Tensor;

struct Param {
  std::string name;
  int group = 0;
  Tensor value;
  Tensor grad;  // same shape as value once allocated; undefined until the first accumulate/zero_grad

  Param() = default;
  Param(std::string n, int g, Tensor v) : name(std::move(n)), group(g), value(std::move(v)) {}
  // grad += g (allocating a zero grad first when needed). g must have value's element count.
  void accumulate(const Tensor& g);
  // The gradient buffer, zero-allocated on first use (for kernels that scatter-add into it).
  Tensor& grad_buffer();
  void zero_grad();
};

// Non-trainable state saved with the model (running statistics, masks kept as floats).
struct StateBuffer {
  std::string name;
  Tensor value;
};

class Module {
 public:
  virtual ~Module() = default;
  // Every parameter, in a fixed order (optimiser state and checkpoints are keyed by name, not order).
  virtual void collect_params(std::vector<Param*>& out) = 0;
  virtual void collect_buffers(std::vector<StateBuffer*>& out) {}

  std::vector<Param*> params();
  std::vector<StateBuffer*> buffers();
  void zero_grad();
  int64_t param_count();
  // Parameters and buffers as "<prefix><name>" tensors.
  void save(io::Checkpoint& ck, const std::string& prefix);
  // Loads every parameter and buffer by name; an Error names the checkpoint, the tensor and the shapes.
  void load(const io::Checkpoint& ck, const std::string& prefix);
  // The first parameter or buffer holding a NaN or an infinity, or "" (a full read back: not per step).
  std::string first_nonfinite();
};

}  // namespace stylerf::nn
