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

// The 8 columns a work-item of a (ceil(cols / 8), rows) range owns in a row-major [rows, cols] matrix:
// declares j (the first column), width (<= 8, fewer at the right edge) and o (the offset of row n's
// column j), and returns from the kernel past the matrix.
#define COLUMN_BLOCK_OR_RETURN(rows, cols)                     \
  const int j = get_global_id(0) * 8, n = get_global_id(1);    \
  if (j >= (cols) || n >= (rows)) return;                      \
  const int width = min(8, (cols) - j);                        \
  const long o = (long)n * (cols) + j;

// The lane loop of a chunked whole-tensor reduction (partials[p] over [p * chunk, min((p + 1) * chunk, n)),
// one work-group of `lanes` a chunk): i runs over chunk get_group_id(0), lane get_local_id(0) taking every
// lanes-th element from its own (neighbouring lanes read neighbouring floats).
#define FOR_CHUNK_ELEMENTS(i, n, chunk, lanes)                                                      \
  for (int i = (int)get_group_id(0) * (chunk) + (int)get_local_id(0),                              \
           i##_end = min((int)get_group_id(0) * (chunk) + (chunk), (n));                           \
       i < i##_end; i += (lanes))

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
