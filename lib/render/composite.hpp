// Volume compositing along rays over a compacted sample list (lib/render/ray_march.hpp), forward and
// backward, and the op that drops samples of negligible weight.
//
// Per ray r with samples i in [offset_r, offset_r + count_r):
//   x_i = sigma_i * delta_i (0 when delta_i <= 0; negative/NaN sigma counts as 0), alpha_i = 1 - exp(-x_i),
//   T_i = prod_{j<i} exp(-x_j), w_i = T_i alpha_i,
//   acc = sum w_i,  depth = sum w_i t_i (no background term: divide by acc, or add (1-acc) far, if wanted),
//   value = sum w_i c_i + (1 - acc) * background   (background only when given).
// Values have C channels (3 for RGB; the feature stage composites more with the same op).
#pragma once
#include <vector>

#include "host/tensor.hpp"
#include "lib/render/ray_march.hpp"

namespace stylerf::render {

struct Composited {
  Tensor value;    // [R,C]
  Tensor acc;      // [R]
  Tensor depth;    // [R]
  Tensor weights;  // [S]
};

// sigma [S], values [S,C], background [C] or undefined (none).
Composited composite_forward(const Samples& s, const Tensor& sigma, const Tensor& values, const Tensor& background);

struct CompositeGrads {
  Tensor dsigma;   // [S]
  Tensor dvalues;  // [S,C]
};
// Upstream gradients dvalue [R,C], dacc [R], ddepth [R]; any may be undefined (zero).
CompositeGrads composite_backward(const Samples& s, const Tensor& sigma, const Tensor& values,
                                  const Tensor& background, const Tensor& dvalue, const Tensor& dacc,
                                  const Tensor& ddepth);

// Samples with w >= threshold, in order: indices into the sample list and the new per-ray offset/count.
struct Kept {
  int64_t count = 0;
  Tensor index;       // [K] int32 bits
  Tensor ray_offset;  // [R] int32 bits
  Tensor ray_count;   // [R] int32 bits
};
Kept keep_by_weight(const Samples& s, const Tensor& weights, float threshold = 1e-4f);

// rows [K, C] = src[index[k], :] for a float or int32-bits src [S, C] (or [S]).
Tensor gather_rows(const Tensor& src, const Tensor& index, int64_t count);

// The inverse: out [total, C] zero-filled, out[index[k], :] = rows[k, :] (values of kept samples back in
// the full list; TensoRF composites all samples with zero colour for the dropped ones). Its backward is
// gather_rows.
Tensor scatter_rows(const Tensor& rows, const Tensor& index, int64_t total);

// The compacted sample list of the kept samples (positions, t, deltas, ray index gathered; offsets/counts
// from keep_by_weight).
Samples compact(const Samples& s, const Kept& k);

}  // namespace stylerf::render
