// Internals shared by conv.cpp (stride-1 "same" conv2d) and conv_strided.cpp (general k x k conv with
// stride and zero padding): the one process-wide im2col scratch buffer and its size limit.
#pragma once
#include <CL/cl.h>

#include <cstddef>

namespace stylerf::nn::detail {

// The device's max allocation, or STYLERF_CONV_SCRATCH_BYTES if smaller.
size_t conv_scratch_limit_bytes();

// The col scratch buffer with room for at least `floats` floats. Grown, never shrunk; conv calls are
// serialised on the one in-order queue, so reusing it between calls (and between the two convs) is safe.
cl_mem conv_scratch(size_t floats);

}  // namespace stylerf::nn::detail
