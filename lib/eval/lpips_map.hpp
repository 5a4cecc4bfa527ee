// The per-position LPIPS distance of one tap, forward and backward (kernels/lpips.cl):
//
//   d[p] = sum_c w[c] * (a[c,p] / (||a[.,p]|| + eps) - b[c,p] / (||b[.,p]|| + eps))^2,   eps = 1e-10,
//
// ||.|| the L2 norm over channels at position p, as the official lpips (normalize_tensor, then the v0.1
// linear head applied to the squared difference). Finite for every finite input: an all-zero position
// counts as the zero vector, and features of any magnitude (1e30 included) are normalised without
// overflow.
#pragma once
#include "host/tensor.hpp"

namespace stylerf::eval {

constexpr float kLpipsEps = 1e-10f;  // must match LPIPS_EPS in kernels/lpips.cl

// fa, fb [1,C,H,W], w [C] -> d [H*W].
host::Tensor lpips_distance_map(const host::Tensor& fa, const host::Tensor& fb, const host::Tensor& w);
// d (sum_p dd[p] d[p]) / d fa for dd [H*W] -> [1,C,H,W] (for losses on the LPIPS distance).
host::Tensor lpips_distance_map_backward(const host::Tensor& fa, const host::Tensor& fb, const host::Tensor& w,
                                         const host::Tensor& dd);

}  // namespace stylerf::eval
