// nn::linear: y = x W + b for a batch of rows (the DST's 1024 -> 1024 map, the feature grid's basis
// matrix, any 1x1 conv applied to per-ray rows). Products are GEMMs (host/gemm.hpp), the bias add and
// its gradient are kernels/linear.cl.
//
// Shapes: x [N, in], W [in, out] (the transpose of PyTorch's nn.Linear.weight), b [out] or undefined,
// y [N, out]. N = 0 is refused with an Error: device tensors cannot be empty here, so callers skip an
// empty batch (e.g. no kept samples) before calling.
#pragma once
#include "host/tensor.hpp"
#include "lib/nn/module.hpp"

namespace stylerf::nn {

using host::Tensor;

Tensor linear_forward(const Tensor& x, const Tensor& w, const Tensor& b);
// y [N, out] += b [out] on every row, in place (linear_forward's bias step).
void linear_add_bias(Tensor& y, const Tensor& b);

// Ops convention (nn/ops.hpp): fresh gradient tensors, each undefined unless asked for.
//   dx = dy W^T,  dW = x^T dy,  db = sum over rows of dy.
struct LinearGrads {
  Tensor dx, dw, db;
};
LinearGrads linear_backward(const Tensor& x, const Tensor& w, const Tensor& dy, bool need_dx, bool need_dw,
                            bool need_db);

// Module convention (nn/module.hpp): ACCUMULATES dW into w.grad and db into b->grad (b may be null: no
// bias), with the GEMM's beta = 1 rather than a separate add; returns dx (undefined unless need_dx).
Tensor linear_backward(const Tensor& x, Param& w, Param* b, const Tensor& dy, bool need_dx);

}  // namespace stylerf::nn
