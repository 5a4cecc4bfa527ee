// IEEE 754 binary16 ("half") on the host, as raw bits: what F16 tensors (host/dtype.hpp) hold and what
// OpenCL's vload_half reads. Conversion rounds to nearest, ties to even, as vstore_half_rte does: values past
// the largest half (65504) become infinity, tiny ones subnormal or zero, NaN stays NaN.
#pragma once
#include <cstddef>
#include <cstdint>

namespace stylerf::host {

uint16_t float_to_half(float f);
float half_to_float(uint16_t h);

// n values, elementwise.
void floats_to_halves(const float* in, size_t n, uint16_t* out);
void halves_to_floats(const uint16_t* in, size_t n, float* out);

}  // namespace stylerf::host
