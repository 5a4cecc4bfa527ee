// Column reductions of a row-major [rows, cols] matrix (per-channel statistics of per-point features, of
// style features, and the sums their backward passes need); lib/nn/columns.cpp. Two stages: partial sums
// over blocks of rows here, then linear_bias_grad (kernels/linear.cl) adds the partials in a fixed order.

// Global (ceil(cols/8), parts); part p sums rows [p*rows_per_part, min(rows, (p+1)*rows_per_part)).
//   mode 0: sum a            mode 1: sum (a - center)^2            mode 2: sum a * b
// Writes partial[p, cols]. Rows are summed in blocks of 64 (as linear_bias_grad) to bound rounding.
__kernel void column_partial_sums(__global const float* a, __global const float* b, __global const float* center,
                                  __global float* partial, int rows, int cols, int rows_per_part, int mode) {
  const int j = get_global_id(0) * 8, p = get_global_id(1);
  if (j >= cols) return;
  const int width = min(8, cols - j);
  const int r0 = p * rows_per_part, r1 = min(rows, r0 + rows_per_part);
  float c[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  if (mode == 1)
    for (int k = 0; k < width; ++k) c[k] = center[j + k];
  float total[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  for (int n0 = r0; n0 < r1; n0 += 64) {
    const int n1 = min(n0 + 64, r1);
    float acc[8] = {0, 0, 0, 0, 0, 0, 0, 0};
    for (int n = n0; n < n1; ++n) {
      const long o = (long)n * cols + j;
      if (mode == 0) {
        for (int k = 0; k < width; ++k) acc[k] += a[o + k];
      } else if (mode == 1) {
        for (int k = 0; k < width; ++k) {
          const float d = a[o + k] - c[k];
          acc[k] = fma(d, d, acc[k]);
        }
      } else {
        for (int k = 0; k < width; ++k) acc[k] = fma(a[o + k], b[o + k], acc[k]);
      }
    }
    for (int k = 0; k < width; ++k) total[k] += acc[k];
  }
  for (int k = 0; k < width; ++k) partial[(long)p * cols + j + k] = total[k];
}

// out[j] = scale * in[j], or sqrt(scale * in[j]) when take_sqrt (a variance's sum of squares -> std).
__kernel void column_finish(__global const float* in, __global float* out, int cols, float scale, int take_sqrt) {
  const int j = get_global_id(0);
  if (j >= cols) return;
  const float v = scale * in[j];
  out[j] = take_sqrt ? sqrt(v) : v;
}
