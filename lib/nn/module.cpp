#include "lib/nn/module.hpp"

#include "host/error.hpp"
#include "lib/io/checkpoint.hpp"
#include "lib/nn/checks.hpp"
#include "lib/nn/ops.hpp"

namespace stylerf::nn {

using host::Error;

Tensor& Param::grad_buffer() {
  if (!grad.defined() || grad.numel() != value.numel()) grad = Tensor::zeros(value.shape(), "gradient of " + name);
  return grad;
}

void Param::accumulate(const Tensor& g) {
  if (g.numel() != value.numel())
    throw Error("gradient of " + name + " has shape " + host::shape_str(g.shape()) + ", parameter has " +
                host::shape_str(value.shape()));
  if (!grad.defined() || grad.numel() != value.numel()) {
    grad = g.clone().reshape(value.shape());
    return;
  }
  axpby(1.0f, g.reshape(grad.shape()), 1.0f, grad);
}

void Param::zero_grad() {
  if (grad.defined() && grad.numel() == value.numel())
    grad.zero();
  else
    grad = Tensor::zeros(value.shape(), "gradient of " + name);
}

std::vector<Param*> Module::params() {
  std::vector<Param*> out;
  collect_params(out);
  return out;
}

std::vector<StateBuffer*> Module::buffers() {
  std::vector<StateBuffer*> out;
  collect_buffers(out);
  return out;
}

void Module::zero_grad() {
  for (Param* p : params()) p->zero_grad();
}

int64_t Module::param_count() {
  int64_t n = 0;
  for (Param* p : params()) n += p->value.numel();
  return n;
}

void Module::save(io::Checkpoint& ck, const std::string& prefix) {
  for (Param* p : params()) ck.put(prefix + p->name, p->value);
  for (StateBuffer* b : buffers()) ck.put(prefix + b->name, b->value);
}

void Module::load(const io::Checkpoint& ck, const std::string& prefix) {
  for (Param* p : params()) {
    p->value = ck.device(prefix + p->name, p->value.shape());
    p->grad = Tensor();
  }
  for (StateBuffer* b : buffers()) b->value = ck.device(prefix + b->name, b->value.shape());
}

std::string Module::first_nonfinite() {
  for (Param* p : params())
    if (has_nonfinite(p->value)) return p->name;
  for (StateBuffer* b : buffers())
    if (has_nonfinite(b->value)) return b->name;
  return "";
}

}  // namespace stylerf::nn
