// Compositing op 2 (kernels/composite.cl): a weighted sum of C-channel values over a compacted list of
// kept samples (lib/render/composite.hpp's keep_by_weight + compact), forward and backward.
//   out_r = sum_{k in ray r} w_k v_k  [R, C],   acc_r = sum_{k in ray r} w_k  [R]
// (acc over the kept samples: what stage 3's DST bias multiplies, so that deferred and per-point style
// transforms agree exactly). Vectorised over channels (16 at a time at C = 256); the cost is that of the
// kept samples, and no [all samples, C] buffer exists.
// The background term out += (1 - acc_all) bg is separate (background_forward/backward): it uses the
// opacity of all samples, from weights_forward.
#pragma once
#include <string>
#include <vector>

#include "host/tensor.hpp"
#include "lib/render/ray_march.hpp"

namespace stylerf::render {

// The layout of a compacted list: per-ray offset and count [R] and each entry's ray [K], all I32. The
// forward reads the offsets and counts, the backward the ray index.
struct KeptLayout {
  int64_t count = 0;  // K
  Tensor ray_offset, ray_count, ray_index;
  int64_t rays() const { return ray_count.numel(); }
};

struct CompositedValues {
  Tensor value;  // [R, C]
  Tensor acc;    // [R]
};
// The build options of kernels/composite.cl's value kernels, one per vector width a channel count can
// select: a stage that builds its programs ahead of its first step builds all of them.
std::vector<std::string> composite_value_build_options();

// w [K], values [K, C].
CompositedValues composite_values_forward(const KeptLayout& l, const Tensor& w, const Tensor& values);

// The same with entry k's value row values[rows[k]] (rows [K] I32, each in [0, values rows)): equal to
// composite_values_forward(l, w, gather_rows(values, rows, K)) without the gathered copy. Inference only
// (the grouped renderer's merge, lib/model/ray_pipeline.hpp); the gather-then-sum form has the backward.
CompositedValues composite_values_forward(const KeptLayout& l, const Tensor& w, const Tensor& values,
                                          const Tensor& rows);

struct CompositeValuesGrads {
  Tensor dvalues;  // [K, C]
  Tensor dw;       // [K]
};
// dvalue [R, C] and dacc [R] may be undefined (zero).
CompositeValuesGrads composite_values_backward(const KeptLayout& l, const Tensor& w, const Tensor& values,
                                               const Tensor& dvalue, const Tensor& dacc);

// value [R, C] += (1 - acc [R]) * bg [C], in place.
void background_forward(Tensor& value, const Tensor& acc, const Tensor& bg);
// The gradient w.r.t. acc of that term, -<dvalue_r, bg>: written to dacc, or added to it when accumulate.
void background_backward(const Tensor& dvalue, const Tensor& bg, Tensor& dacc, bool accumulate);

}  // namespace stylerf::render
