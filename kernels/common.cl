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

// Blocked float sum of p[0, n): float8 accumulators, a fresh one every BLOCK vectors, then the scalar tail.
inline float blocked_sum(__global const float* p, int n) {
  const int n8 = n / 8;
  float8 total = 0.0f;
  for (int b = 0; b < n8; b += BLOCK) {
    const int e = min(b + BLOCK, n8);
    float8 acc = 0.0f;
    for (int i = b; i < e; ++i) acc += vload8(i, p);
    total += acc;
  }
  float s = hsum8(total);
  for (int i = n8 * 8; i < n; ++i) s += p[i];
  return s;
}

// A work-group's lanes combine their values in buf[0, lanes) (lanes a power of two, every lane calling,
// buf filled and a barrier passed): buf[0] = OP over all of them, in a fixed tree order (deterministic).
// OP is a two-argument function or macro, e.g. fmax or TREE_ADD.
#define TREE_ADD(a, b) ((a) + (b))
#define LOCAL_TREE(buf, lanes, OP)                                                   \
  for (int tree_s = (lanes) / 2; tree_s > 0; tree_s >>= 1) {                         \
    const int tree_l = (int)get_local_id(0);                                         \
    if (tree_l < tree_s) (buf)[tree_l] = OP((buf)[tree_l], (buf)[tree_l + tree_s]);  \
    barrier(CLK_LOCAL_MEM_FENCE);                                                    \
  }

#endif  // STYLERF_COMMON_CL
