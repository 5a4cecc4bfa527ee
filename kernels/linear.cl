// The bias parts of nn::linear (lib/nn/linear.cpp); the products themselves are GEMMs (host/gemm.hpp).
//   forward:  y[n, j] += b[j]                 (after y = x W)
//   backward: db[j] (+)= sum over n of dy[n, j]
// A work-item owns 8 consecutive columns and moves them as one float8 (vload8 needs only float
// alignment, so any `cols` works); the last group of a row takes the scalar path when cols % 8 != 0.

// Global: (ceil(cols/8), rows).
__kernel void linear_bias_add(__global float* y, __global const float* b, int rows, int cols) {
  const int j = get_global_id(0) * 8, n = get_global_id(1);
  if (j >= cols || n >= rows) return;
  __global float* yr = y + (long)n * cols;
  if (j + 8 <= cols) {
    vstore8(vload8(0, yr + j) + vload8(0, b + j), 0, yr + j);
  } else {
    for (int k = j; k < cols; ++k) yr[k] += b[k];
  }
}

// Global: ceil(cols/8). Rows are summed in blocks of 64 into a fresh float8 before joining the total,
// so the rounding error grows with 64 + rows / 64 rather than with rows (4096 rays: ~128 vs 4096 ulps).
// accumulate != 0 adds to db (a Param's gradient), else overwrites it.
#define ROW_BLOCK 64
__kernel void linear_bias_grad(__global const float* dy, __global float* db, int rows, int cols, int accumulate) {
  const int j = get_global_id(0) * 8;
  if (j >= cols) return;
  const int width = min(8, cols - j);
  float8 total = 0.0f;
  for (int n0 = 0; n0 < rows; n0 += ROW_BLOCK) {
    const int n1 = min(n0 + ROW_BLOCK, rows);
    float8 acc = 0.0f;
    if (width == 8) {
      for (int n = n0; n < n1; ++n) acc += vload8(0, dy + (long)n * cols + j);
    } else {
      float part[8] = {0, 0, 0, 0, 0, 0, 0, 0};
      for (int n = n0; n < n1; ++n)
        for (int k = 0; k < width; ++k) part[k] += dy[(long)n * cols + j + k];
      acc = vload8(0, part);
    }
    total += acc;
  }
  float out[8];
  vstore8(total, 0, out);
  for (int k = 0; k < width; ++k) db[j + k] = accumulate ? db[j + k] + out[k] : out[k];
}
