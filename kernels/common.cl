// Helpers shared by every program: the runtime puts this file in front of each program's source
// (host/runtime.cpp, build_program), so a kernel file uses them without defining its own copy.
#ifndef STYLERF_COMMON_CL
#define STYLERF_COMMON_CL

// Blocked float sums restart their accumulator every BLOCK vectors (or elements), so rounding error grows
// with BLOCK + n / BLOCK terms rather than n (reduce.cl, norm.cl, loss.cl).
#define BLOCK 64

// Horizontal sum of a float8 in a fixed order (pairwise: lo + hi, then halves).
inline float hsum8(float8 v) {
  float4 a = v.lo + v.hi;
  float2 b = a.lo + a.hi;
  return b.x + b.y;
}

#endif  // STYLERF_COMMON_CL
