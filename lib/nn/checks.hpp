// Argument and value checks shared by the NN ops.
#pragma once
#include <cstdint>

#include "host/tensor.hpp"

namespace stylerf::nn {

// True when x holds a NaN or an infinity (a device-side two-stage count; reads back one float).
// Training loops use it to stop on a diverged loss or gradient.
bool has_nonfinite(const host::Tensor& x);  // lib/nn/reduce.cpp

// A 4-D tensor [N,C,H,W] seen as nc = N*C channels of hw = H*W floats.
struct ChannelDims {
  int64_t n = 0, c = 0, h = 0, w = 0;
  int nc = 0, hw = 0;
};
// Throws an Error "<op>: <name> ..." when x is undefined, not 4-D, empty, or too large for int indexing.
ChannelDims expect_nchw(const host::Tensor& x, const char* op, const char* name);  // lib/nn/checks.cpp

// Throws an Error "<op>: <name> is undefined" / "... has N elements, too many ..." for a flat tensor
// used by an elementwise op or a reduction; returns numel as int.
int expect_flat(const host::Tensor& x, const char* op, const char* name);  // lib/nn/checks.cpp

}  // namespace stylerf::nn
