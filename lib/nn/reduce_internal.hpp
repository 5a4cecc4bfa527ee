// Internals of the two-stage reductions (kernels/reduce.cl), shared by reduce.cpp and loss.cpp.
#pragma once
#include <cstdint>

#include "host/tensor.hpp"

namespace stylerf::nn::detail {

// Split of n elements into `parts` contiguous chunks of `chunk` elements (a multiple of 8; the last
// chunk may be shorter). Depends on n only, which makes the reductions deterministic.
struct Partition {
  int parts = 1, chunk = 8;
};
Partition partition(int64_t n);

// Stage 2: a [1] tensor holding scale * sum(partials).
host::Tensor finish_sum(const host::Tensor& partials, int parts, float scale);

}  // namespace stylerf::nn::detail
