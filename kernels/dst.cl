// The elementwise parts of the deferred style transformation (StyleRF Sec. 3.3), lib/style/dst.cpp; its
// products (covariance, the 1024 -> 1024 map, T, the unzip conv) are GEMMs.

// Global (ceil(cols/8), rows): y[n, j] = x[n, j] - v[j] (the style features centred by their means).
__kernel void subtract_row_vector(__global const float* x, __global const float* v, __global float* y, int rows,
                                  int cols) {
  COLUMN_BLOCK_OR_RETURN(rows, cols)
  for (int k = 0; k < width; ++k) y[o + k] = x[o + k] - v[j + k];
}

// Global (ceil(cols/8), rows): y[n, j] = x[n, j] * v[j] (W' = M diag(std), and dM = dW' diag(std)).
__kernel void scale_columns(__global const float* x, __global const float* v, __global float* y, int rows, int cols) {
  COLUMN_BLOCK_OR_RETURN(rows, cols)
  for (int k = 0; k < width; ++k) y[o + k] = x[o + k] * v[j + k];
}

// The style statistics' backward, per style position l and channel j (L positions, s [L, C]):
//   centred = s - mean           -> ds += dcentred - sum_l(dcentred) / L
//   mean                         -> ds += dmean / L
//   std = sqrt(sum (s - mean)^2 / (L - 1))   -> ds += dstd (s - mean) / ((L - 1) std)
// A constant channel (std = 0, a flat-colour style) has no derivative of its std; its subgradient 0 is
// used (PyTorch would give NaN there). Any of dcentred / dmean / dstd may be absent (has_* = 0).
// Global (ceil(cols/8), rows).
__kernel void style_stats_backward(__global const float* s, __global const float* mean, __global const float* std,
                                   __global const float* dcentred, __global const float* sum_dcentred,
                                   __global const float* dmean, __global const float* dstd, __global float* ds,
                                   int rows, int cols, int has_centred, int has_mean, int has_std) {
  COLUMN_BLOCK_OR_RETURN(rows, cols)
  const float inv_l = 1.0f / (float)rows;
  for (int k = 0; k < width; ++k) {
    float g = 0.0f;
    if (has_centred) g += dcentred[o + k] - sum_dcentred[j + k] * inv_l;
    if (has_mean) g += dmean[j + k] * inv_l;
    if (has_std && rows > 1) {
      const float sd = std[j + k];
      if (sd > 0.0f) g += dstd[j + k] * (s[o + k] - mean[j + k]) / ((float)(rows - 1) * sd);
    }
    ds[o + k] = g;
  }
}
