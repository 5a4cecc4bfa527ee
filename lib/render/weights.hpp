// Compositing op 1 (kernels/composite.cl): densities to per-sample weights, forward and backward.
//   x_i = sigma_i delta_i (0 for delta <= 0; negative or NaN sigma counts as 0), alpha_i = 1 - exp(-x_i),
//   T_i = prod_{j<i} exp(-x_j), w_i = T_i alpha_i;   acc_r = sum_i w_i,  depth_r = sum_i w_i t_i.
// Backward takes the gradient w.r.t. each weight plus optional gradients of acc and depth (folded in as
// dw_i += dacc_r + ddepth_r t_i) and returns dsigma.
#pragma once
#include "host/tensor.hpp"
#include "lib/render/ray_march.hpp"

namespace stylerf::render {

struct Weights {
  Tensor w;      // [S]
  Tensor acc;    // [R]
  Tensor depth;  // [R] sum w t (not divided by acc)
};

Weights weights_forward(const Samples& s, const Tensor& sigma);
// dw [S], dacc [R], ddepth [R]: any may be undefined (zero). Returns dsigma [S].
Tensor weights_backward(const Samples& s, const Tensor& sigma, const Tensor& dw, const Tensor& dacc,
                        const Tensor& ddepth);

}  // namespace stylerf::render
