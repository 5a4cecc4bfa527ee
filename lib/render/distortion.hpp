// The distortion loss of Mip-NeRF 360 (Barron et al. 2022) on a ray's sample weights (kernels/composite.cl):
// it is small when a ray's weight sits in one short interval, and large when it is spread along the ray as a
// fog. With distances normalised as u = t * inv_len and each sample an interval of length d = step * inv_len:
//   L_r = sum_i sum_j w_i w_j |u_i - u_j| + (d / 3) sum_i w_i^2
// Forward and backward in one pass over each ray (the gradient needs the same running sums).
#pragma once
#include "host/tensor.hpp"
#include "lib/render/ray_march.hpp"

namespace stylerf::render {

struct Distortion {
  Tensor loss;  // [R] scale * L_r
  Tensor dw;    // [S] scale * dL_r / dw_i
};
// w [S]: the samples' weights (weights_forward), in s's ray lists with t increasing along each ray.
Distortion distortion_forward_backward(const Samples& s, const Tensor& w, float inv_len, float d, float scale);

}  // namespace stylerf::render
