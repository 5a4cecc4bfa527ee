// Selecting and moving samples between the full list of a march (lib/render/ray_march.hpp) and the
// compacted list of kept samples: dropping samples of negligible weight, gather/scatter of rows, compaction.
// Compositing itself is two ops: lib/render/weights.hpp (sigma -> weights) and
// lib/render/composite_values.hpp (a weighted sum of C-channel values over the kept samples).
#pragma once
#include <vector>

#include "host/tensor.hpp"
#include "lib/render/ray_march.hpp"

namespace stylerf::render {

// Samples with w >= threshold, in order: indices into the sample list and the new per-ray offset/count.
struct Kept {
  int64_t count = 0;
  Tensor index;       // [K] I32
  Tensor ray_offset;  // [R] I32
  Tensor ray_count;   // [R] I32
};
// weights [S] F32; s.ray_offset / s.ray_count I32.
Kept keep_by_weight(const Samples& s, const Tensor& weights, float threshold = 1e-4f);

// rows [count, C] = src[index[k], :] for an F32 or I32 src [S, C] (or [S]); index I32 (at least count
// entries). The rows are copied as 32-bit words, so I32 values come through bit-exact; the result has src's
// dtype.
Tensor gather_rows(const Tensor& src, const Tensor& index, int64_t count);

// The inverse: out [total, C] zero-filled, out[index[k], :] = rows[k, :] (per-sample gradients of kept
// samples back in the full list, zero for the dropped ones). Its backward is gather_rows. Same dtypes as
// gather_rows; the result has rows' dtype.
Tensor scatter_rows(const Tensor& rows, const Tensor& index, int64_t total);

// The compacted sample list of the kept samples (positions, t, deltas, ray index gathered; offsets/counts
// from keep_by_weight).
Samples compact(const Samples& s, const Kept& k);

}  // namespace stylerf::render
