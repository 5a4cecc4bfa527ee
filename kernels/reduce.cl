// Deterministic two-stage reductions over a whole tensor.
//
// Stage 1: `parts` work-items, work-item p sums the contiguous chunk [p*chunk, min((p+1)*chunk, n)) into
// partials[p] (float8 accumulators, blocked: a fresh accumulator every BLOCK vectors keeps the rounding
// error proportional to BLOCK + chunk / (8 * BLOCK) rather than chunk). Stage 2: one work-item adds the
// partials in order. The split depends on n only, so results do not depend on scheduling.
// chunk is a multiple of 8, so every chunk but the last starts 32-byte aligned.
// BLOCK, hsum8 and blocked_sum come from kernels/common.cl, which the runtime puts in front of every program.

__kernel void sum_partials(__global const float* x, __global float* partials, int n, int chunk) {
  const int p = get_global_id(0);
  const int begin = p * chunk;
  if (begin >= n) return;
  partials[p] = blocked_sum(x + begin, min(begin + chunk, n) - begin);
}

// Counts the NaN and Inf elements of each chunk. Tests the exponent bits rather than calling isfinite,
// so a build with fast-math options cannot optimise the check away.
__kernel void nonfinite_partials(__global const float* x, __global float* partials, int n, int chunk) {
  const int p = get_global_id(0);
  const int begin = p * chunk;
  if (begin >= n) return;
  const int end = min(begin + chunk, n);
  __global const uint* u = (__global const uint*)x;
  uint count = 0;
  for (int i = begin; i < end; ++i) count += ((u[i] & 0x7f800000u) == 0x7f800000u) ? 1u : 0u;
  partials[p] = (float)count;
}

// out[0] = scale * sum(partials[0..parts)), in a fixed order.
__kernel void sum_finish(__global const float* partials, __global float* out, int parts, float scale) {
  if (get_global_id(0) != 0) return;
  float total = 0.0f;
  for (int b = 0; b < parts; b += BLOCK) {
    const int e = min(b + BLOCK, parts);
    float acc = 0.0f;
    for (int i = b; i < e; ++i) acc += partials[i];
    total += acc;
  }
  out[0] = total * scale;
}
