// The general strided ops of lib/nn/conv_strided.cpp and lib/nn/spatial.cpp (AlexNet's trunk): im2col /
// col2im for a k x k convolution with stride s and zero padding p (any k >= 1, s >= 1, p >= 0), and
// k x k max pooling with stride s, no padding. NCHW float32. Output sizes floor, as torch's Conv2d and
// MaxPool2d (ceil_mode=False): Ho = (H + 2p - k) / s + 1, pooling Ho = (H - k) / s + 1; the host checks
// that they are >= 1.

// The output columns ox in [*lo, *hi) whose input column ox * S + off lies in [0, W); both clamped to
// [0, Wo], lo <= hi.
inline void inside_columns(int off, int S, int W, int Wo, int* lo, int* hi) {
  int l = off < 0 ? (-off + S - 1) / S : 0;  // ceil(-off / S)
  int h = W - 1 - off >= 0 ? (W - 1 - off) / S + 1 : 0;
  l = min(l, Wo);
  *lo = l;
  *hi = max(min(h, Wo), l);
}

// ---- im2col ----------------------------------------------------------------------------------
// col[r, (oy - oy0) * Wo + ox] = x[c, oy * S + ky - P, ox * S + kx - P] (0 in the padding),
// r = (c * K + ky) * K + kx, for the output rows oy in [oy0, oy0 + rows) (the host chunks Ho when the
// whole col would not fit). Global: (rows, C * K * K); one work-item per (output row, col row).
__kernel void im2col_strided(__global const float* x, int x_off, __global float* col, int C, int H, int W, int K,
                             int S, int P, int Wo, int oy0, int rows) {
  const int ly = get_global_id(0);
  const int r = get_global_id(1);
  if (ly >= rows || r >= C * K * K) return;
  const int kx = r % K, ky = (r / K) % K, c = r / (K * K);
  __global float* dst = col + ((long)r * rows + ly) * Wo;
  const int sy = (oy0 + ly) * S + ky - P;
  if (sy < 0 || sy >= H) {
    int i = 0;
    for (; i + 8 <= Wo; i += 8) vstore8((float8)(0.0f), 0, dst + i);
    for (; i < Wo; ++i) dst[i] = 0.0f;
    return;
  }
  __global const float* src = x + x_off + ((long)c * H + sy) * W;
  const int off = kx - P;  // dst[ox] = src[ox * S + off]
  int lo, hi;
  inside_columns(off, S, W, Wo, &lo, &hi);
  int ox = 0;
  for (; ox < lo; ++ox) dst[ox] = 0.0f;
  if (S == 1) {
    for (; ox + 8 <= hi; ox += 8) vstore8(vload8(0, src + ox + off), 0, dst + ox);
  } else if (S == 2) {
    // vload16 reads one float past the last one used: stop while that is still inside the row.
    for (; ox + 8 <= hi && 2 * ox + off + 16 <= W; ox += 8) vstore8(vload16(0, src + 2 * ox + off).even, 0, dst + ox);
  }
  for (; ox < hi; ++ox) dst[ox] = src[ox * S + off];
  for (; ox < Wo; ++ox) dst[ox] = 0.0f;
}

// ---- col2im (gather) -------------------------------------------------------------------------
// The adjoint of im2col: dx[c, y, x] = sum of every col entry that im2col read from x[c, y, x], i.e. over
// (ky, kx, oy, ox) with oy * S + ky - P = y and ox * S + kx - P = x. Each work-item owns one input row and
// adds into it, so no two work-items write the same element (no atomics). Only col rows for output rows
// [oy0, oy0 + rows) are present; input rows [ylo, ylo + nrows) are updated (the host launches those the
// chunk can reach). accumulate == 0 writes the row (zeros where no tap reads it: rows and columns that
// the flooring leaves out, or that only the padding would have covered); != 0 adds to it (later chunks).
// Global: (nrows, C).
__kernel void col2im_strided(__global const float* col, __global float* dx, int dx_off, int C, int H, int W, int K,
                             int S, int P, int Wo, int oy0, int rows, int ylo, int nrows, int accumulate) {
  const int ly = get_global_id(0);
  const int c = get_global_id(1);
  if (ly >= nrows || c >= C) return;
  const int y = ylo + ly;
  const long plane = (long)rows * Wo;
  __global float* dst = dx + dx_off + ((long)c * H + y) * W;
  if (!accumulate) {
    int i = 0;
    for (; i + 8 <= W; i += 8) vstore8((float8)(0.0f), 0, dst + i);
    for (; i < W; ++i) dst[i] = 0.0f;
  }
  for (int ky = 0; ky < K; ++ky) {
    const int t = y + P - ky;  // = oy * S
    if (t < 0 || t % S != 0) continue;
    const int oy = t / S;
    if (oy < oy0 || oy >= oy0 + rows) continue;
    __global const float* base = col + (long)(c * K + ky) * K * plane + (long)(oy - oy0) * Wo;
    for (int kx = 0; kx < K; ++kx) {
      __global const float* src = base + kx * plane;
      const int off = kx - P;  // dst[ox * S + off] += src[ox]
      int lo, hi;
      inside_columns(off, S, W, Wo, &lo, &hi);
      int ox = lo;
      if (S == 1)
        for (; ox + 8 <= hi; ox += 8) vstore8(vload8(0, dst + ox + off) + vload8(0, src + ox), 0, dst + ox + off);
      for (; ox < hi; ++ox) dst[ox * S + off] += src[ox];
    }
  }
}

// ---- k x k max pooling, stride s, no padding ---------------------------------------------------
// y[oy, ox] = max over the window x[oy * S + ky, ox * S + kx], ky, kx < K. The maximum is the first one
// in row-major window order that no later element exceeds (strict >), which the backward routes to.
// One work-item per output row (n, c, oy). Global: (Ho, N * C).
__kernel void maxpool_forward(__global const float* x, __global float* y, int H, int W, int K, int S, int Ho,
                              int Wo) {
  const int oy = get_global_id(0);
  const int nc = get_global_id(1);
  if (oy >= Ho) return;
  __global const float* base = x + ((long)nc * H + oy * S) * W;
  __global float* out = y + ((long)nc * Ho + oy) * Wo;
  for (int ox = 0; ox < Wo; ++ox) {
    __global const float* win = base + ox * S;
    float m = win[0];
    for (int ky = 0; ky < K; ++ky)
      for (int kx = 0; kx < K; ++kx) {
        const float v = win[ky * W + kx];
        if (v > m) m = v;
      }
    out[ox] = m;
  }
}

// dx[y, x] = sum of dy over the windows whose first maximum (as the forward) is x[y, x]. Windows overlap
// when S < K, so each work-item owns one input row (n, c, y), zeroes it and adds the dy of the windows
// covering that row whose maximum lies in it: no atomics, and rows or columns in no window stay 0.
// Global: (H, N * C).
__kernel void maxpool_backward(__global const float* x, __global const float* dy, __global float* dx, int H, int W,
                               int K, int S, int Ho, int Wo) {
  const int y = get_global_id(0);
  const int nc = get_global_id(1);
  if (y >= H) return;
  __global float* dst = dx + ((long)nc * H + y) * W;
  for (int i = 0; i < W; ++i) dst[i] = 0.0f;
  // Window rows oy with oy * S <= y < oy * S + K.
  const int oy_lo = y >= K ? (y - K) / S + 1 : 0;
  const int oy_hi = min(Ho - 1, y / S);
  for (int oy = oy_lo; oy <= oy_hi; ++oy) {
    __global const float* base = x + ((long)nc * H + oy * S) * W;
    __global const float* g = dy + ((long)nc * Ho + oy) * Wo;
    const int ky_here = y - oy * S;
    for (int ox = 0; ox < Wo; ++ox) {
      __global const float* win = base + ox * S;
      float m = win[0];
      int by = 0, bx = 0;
      for (int ky = 0; ky < K; ++ky)
        for (int kx = 0; kx < K; ++kx) {
          const float v = win[ky * W + kx];
          if (v > m) {
            m = v;
            by = ky;
            bx = kx;
          }
        }
      if (by == ky_here) dst[ox * S + bx] += g[ox];
    }
  }
}
