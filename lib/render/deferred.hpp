// Deferred shading (kernels/composite.cl): a head that shades a ray once, from the weighted mean of its
// samples' features, instead of once per sample.
//   forward:  n = F / (a + eps)   (the mean feature; F [R,C] composited features, a [R] their opacity)
//             -> c = head(n)      (the caller's network, [R,C'])
//             -> y = a c          (the ray's colour before any background)
// When a single sample carries a ray's weight, y equals per-sample shading sum_i w_i head(f_i); elsewhere it
// is a different, cheaper model (one network evaluation per ray). eps keeps n finite on empty rays (a = 0,
// where F = 0 as well, so n = 0).
// Each op's backward returns the gradient w.r.t. its array input and *adds* to da, so both ops' opacity
// gradients sum into one [R] tensor.
#pragma once
#include "host/tensor.hpp"

namespace stylerf::render {

using host::Tensor;

constexpr float kDeferredEps = 1e-4f;  // the keep threshold: a ray with any kept sample has a >= it

Tensor opacity_normalise_forward(const Tensor& F, const Tensor& a, float eps = kDeferredEps);
// Returns dF; da [R] accumulates (allocate it zeroed).
Tensor opacity_normalise_backward(const Tensor& F, const Tensor& a, const Tensor& dn, Tensor& da,
                                  float eps = kDeferredEps);

Tensor opacity_scale_forward(const Tensor& c, const Tensor& a);
// Returns dc; da [R] accumulates.
Tensor opacity_scale_backward(const Tensor& c, const Tensor& a, const Tensor& dy, Tensor& da);

}  // namespace stylerf::render
