// Convolution helpers (im2col / col2im with zero or reflect padding, bias) and the spatial ops
// (relu, 2x2 max pooling, x2 nearest upsampling). NCHW float32, stride 1, "same" convolutions.
//
// On PoCL/CPU one work-item runs a whole image row and moves 8 floats at a time (vload8/vstore8);
// only the one or two columns that touch the padding take the scalar path. No float16: PoCL's
// "haswell" CPU target has no AVX-512, so float16 builtins go through an out-of-line ABI (it warns).

// Interleaving masks for shuffle2: (a0 b0 a1 b1 a2 b2 a3 b3) and (a4 b4 ... a7 b7).
#define ZIP_LO (uint8)(0, 8, 1, 9, 2, 10, 3, 11)
#define ZIP_HI (uint8)(4, 12, 5, 13, 6, 14, 7, 15)

// Padding modes, as passed by lib/nn/conv.cpp.
#define PAD_ZERO 0
#define PAD_REFLECT 1

// PyTorch ReflectionPad2d(1): -1 -> 1, n -> n-2 (needs n >= 2; the host checks).
inline int reflect_index(int i, int n) { return i < 0 ? -i : (i >= n ? 2 * n - 2 - i : i); }

// Value of the padded input row `src` (length W) at column sx, which may lie in the padding.
inline float padded_at(__global const float* src, int sx, int W, int mode) {
  if (sx >= 0 && sx < W) return src[sx];
  return mode == PAD_REFLECT ? src[reflect_index(sx, W)] : 0.0f;
}

// ---- im2col ----------------------------------------------------------------------------------
// col[r, (y - y0) * W + x] = padded x[c, y + ky - pad, x + kx - pad], r = (c * K + ky) * K + kx, for the
// output rows y in [y0, y0 + rows) (the host chunks H when the whole col would not fit).
// Global: (rows, C * K * K); one work-item per (output row, col row).
__kernel void im2col(__global const float* x, int x_off, __global float* col, int C, int H, int W, int K, int mode,
                     int y0, int rows) {
  const int ly = get_global_id(0);
  const int r = get_global_id(1);
  if (ly >= rows || r >= C * K * K) return;
  const int pad = K / 2;
  const int kx = r % K, ky = (r / K) % K, c = r / (K * K);
  const int y = y0 + ly;
  __global float* dst = col + (long)r * rows * W + (long)ly * W;
  int sy = y + ky - pad;
  if (sy < 0 || sy >= H) {
    if (mode == PAD_ZERO) {
      int i = 0;
      for (; i + 8 <= W; i += 8) vstore8((float8)(0.0f), 0, dst + i);
      for (; i < W; ++i) dst[i] = 0.0f;
      return;
    }
    sy = reflect_index(sy, H);
  }
  __global const float* src = x + x_off + ((long)c * H + sy) * W;
  const int dx = kx - pad;  // column shift: dst[i] = src[i + dx]
  // Columns whose source lies inside the row: i in [lo, hi).
  const int lo = max(0, -dx), hi = min(W, W - dx);
  int i = 0;
  for (; i < lo; ++i) dst[i] = padded_at(src, i + dx, W, mode);
  for (; i + 8 <= hi; i += 8) vstore8(vload8(0, src + i + dx), 0, dst + i);
  for (; i < W; ++i) dst[i] = padded_at(src, i + dx, W, mode);
}

// ---- col2im (gather) -------------------------------------------------------------------------
// The adjoint of im2col: dx[c, y, x] = sum of every col entry that im2col read from x[c, y, x]. Each
// work-item owns one input row and gathers, so no two work-items write the same element (no atomics).
// With reflect padding an input pixel is also read through the padding: padded row -1 is row 1 and
// padded row H is row H-2 (same for columns), so rows 1 / H-2 (columns 1 / W-2) gather one extra tap.
// Only col rows for output rows [y0, y0 + rows) are present; input rows [ylo, ylo + nrows) are
// updated (the host launches those the chunk can reach). accumulate != 0 adds to dx (later chunks).
// Global: (nrows, C).

// Output rows oy (at most 2) that read input row y through kernel row ky.
inline int taps_from(int y, int k, int H, int pad, int mode, int* o) {
  int n = 0;
  int direct = y - k + pad;
  if (direct >= 0 && direct < H) o[n++] = direct;
  if (mode == PAD_REFLECT && pad == 1) {
    if (k == 0 && y == 1) o[n++] = 0;          // output row 0 read padded row -1 = row 1
    if (k == 2 && y == H - 2) o[n++] = H - 1;  // output row H-1 read padded row H = row H-2
  }
  return n;
}

__kernel void col2im(__global const float* col, __global float* dx, int dx_off, int C, int H, int W, int K, int mode,
                     int y0, int rows, int ylo, int nrows, int accumulate) {
  const int ly = get_global_id(0);
  const int c = get_global_id(1);
  if (ly >= nrows || c >= C) return;
  const int y = ylo + ly;
  const int pad = K / 2;
  const long plane = (long)rows * W;
  __global float* dst = dx + dx_off + ((long)c * H + y) * W;

  // The col rows (ky, oy) that read input row y and are present in this chunk: at most 2 per ky.
  // Found once per row, so the loop over x below only walks pointers.
  __global const float* taps[6];
  int ntaps = 0;
  for (int ky = 0; ky < K; ++ky) {
    int oys[2];
    const int nt = taps_from(y, ky, H, pad, mode, oys);
    for (int t = 0; t < nt; ++t)
      if (oys[t] >= y0 && oys[t] < y0 + rows)
        taps[ntaps++] = col + (long)(c * K + ky) * K * plane + (long)(oys[t] - y0) * W;
  }

  // Direct taps along the row: input column x is read by output column ox = x - kx + pad of col row
  // (ky, kx); the K col rows of one ky are `plane` apart.
  for (int x0 = 0; x0 < W; x0 += 8) {
    const int n = min(8, W - x0);
    float8 acc = (float8)(0.0f);
    for (int t = 0; t < ntaps; ++t) {
      for (int kx = 0; kx < K; ++kx) {
        __global const float* src = taps[t] + kx * plane;
        const int ox0 = x0 - kx + pad;
        if (n == 8 && ox0 >= 0 && ox0 + 8 <= W) {
          acc += vload8(0, src + ox0);
        } else {
          float t8[8] = {0, 0, 0, 0, 0, 0, 0, 0};
          for (int l = 0; l < n; ++l) {
            const int ox = ox0 + l;
            if (ox >= 0 && ox < W) t8[l] = src[ox];
          }
          acc += vload8(0, t8);
        }
      }
    }
    if (n == 8) {
      if (accumulate) acc += vload8(0, dst + x0);
      vstore8(acc, 0, dst + x0);
    } else {
      float t8[8];
      vstore8(acc, 0, t8);
      for (int l = 0; l < n; ++l) dst[x0 + l] = accumulate ? dst[x0 + l] + t8[l] : t8[l];
    }
  }

  // Reflected column taps, kept out of the loop above: output column 0 read padded column -1 = column 1
  // through kx = 0, output column W-1 read padded column W = column W-2 through kx = 2.
  if (mode == PAD_REFLECT && pad == 1) {
    float add1 = 0.0f, add2 = 0.0f;
    for (int t = 0; t < ntaps; ++t) {
      add1 += taps[t][0];                  // kx = 0
      add2 += taps[t][2 * plane + W - 1];  // kx = 2
    }
    dst[1] += add1;
    dst[W - 2] += add2;
  }
}

// ---- bias ------------------------------------------------------------------------------------
// y[n, c, :] += b[c]. Global: (ceil(HW / 8), N * C).
__kernel void bias_add(__global float* y, __global const float* b, int C, int HW) {
  const int i = get_global_id(0) * 8;
  const int nc = get_global_id(1);
  if (i >= HW) return;
  __global float* row = y + (long)nc * HW;
  const float v = b[nc % C];
  if (i + 8 <= HW) {
    vstore8(vload8(0, row + i) + v, 0, row + i);
  } else {
    for (int j = i; j < HW; ++j) row[j] += v;
  }
}

// A convolution's bias gradient, db[c] = sum over n and pixels of dy[n, c, :], first stage: part
// p = n * chunks + k of channel c sums pixels [k * chunk, (k + 1) * chunk) of image n into partial[p, c];
// linear_bias_grad (kernels/linear.cl) then adds each channel's partials in a fixed order
// (lib/nn/columns.cpp, image_channel_sum). One work-item per channel over all pixels left a GPU nearly
// idle. 8 partial sums along the chunk keep the float rounding error ~ sqrt(chunk / 8) ulps. Global:
// (C, N * chunks).
__kernel void channel_partial_sums(__global const float* x, __global float* partial, int N, int C, int HW, int chunk,
                                   int chunks) {
  const int c = get_global_id(0), p = get_global_id(1);
  if (c >= C || p >= N * chunks) return;
  const int n = p / chunks, i0 = (p % chunks) * chunk, i1 = min(HW, i0 + chunk);
  __global const float* row = x + ((long)n * C + c) * HW;
  float8 acc = (float8)(0.0f);
  float tail = 0.0f;
  int i = i0;
  for (; i + 8 <= i1; i += 8) acc += vload8(0, row + i);
  for (; i < i1; ++i) tail += row[i];
  const float4 s4 = acc.lo + acc.hi;
  const float2 s2 = s4.lo + s4.hi;
  partial[(long)p * C + c] = s2.x + s2.y + tail;
}

// ---- relu ------------------------------------------------------------------------------------
// Global: (ceil(n / 8)); each work-item does 8 elements.
__kernel void relu_forward(__global const float* x, __global float* y, int n) {
  const int i = get_global_id(0) * 8;
  if (i >= n) return;
  if (i + 8 <= n) {
    vstore8(fmax(vload8(0, x + i), (float8)(0.0f)), 0, y + i);
  } else {
    for (int j = i; j < n; ++j) y[j] = fmax(x[j], 0.0f);
  }
}

// dx = dy where the output was positive, else 0 (gradient 0 at the kink, as PyTorch).
__kernel void relu_backward(__global const float* y, __global const float* dy, __global float* dx, int n) {
  const int i = get_global_id(0) * 8;
  if (i >= n) return;
  if (i + 8 <= n) {
    const float8 yv = vload8(0, y + i);
    vstore8(select((float8)(0.0f), vload8(0, dy + i), yv > (float8)(0.0f)), 0, dx + i);
  } else {
    for (int j = i; j < n; ++j) dx[j] = y[j] > 0.0f ? dy[j] : 0.0f;
  }
}

// ---- 2x2 max pooling, stride 2 ------------------------------------------------------------------
// One work-item per output row (n, c, oy): reads two input rows 16 floats at a time (2 x float8).
// Global: (Ho, N * C), Ho = H / 2, Wo = W / 2.
__kernel void maxpool2x2_forward(__global const float* x, __global float* y, int H, int W) {
  const int oy = get_global_id(0);
  const int nc = get_global_id(1);
  const int Ho = H / 2, Wo = W / 2;
  if (oy >= Ho) return;
  __global const float* r0 = x + ((long)nc * H + 2 * oy) * W;
  __global const float* r1 = r0 + W;
  __global float* out = y + ((long)nc * Ho + oy) * Wo;
  int ox = 0;
  for (; ox + 8 <= Wo; ox += 8) {
    const float8 m0 = fmax(vload8(0, r0 + 2 * ox), vload8(0, r1 + 2 * ox));
    const float8 m1 = fmax(vload8(0, r0 + 2 * ox + 8), vload8(0, r1 + 2 * ox + 8));
    vstore8(fmax((float8)(m0.even, m1.even), (float8)(m0.odd, m1.odd)), 0, out + ox);
  }
  for (; ox < Wo; ++ox)
    out[ox] = fmax(fmax(r0[2 * ox], r0[2 * ox + 1]), fmax(r1[2 * ox], r1[2 * ox + 1]));
}

// Routes dy to the first maximum of each window in the order (0,0), (0,1), (1,0), (1,1) so ties
// (e.g. a constant input) send the whole gradient to exactly one element. Every dx element is
// written (zeros elsewhere), so dx needs no clearing. Global: (Ho, N * C).
__kernel void maxpool2x2_backward(__global const float* x, __global const float* dy, __global float* dx, int H,
                                  int W) {
  const int oy = get_global_id(0);
  const int nc = get_global_id(1);
  const int Ho = H / 2, Wo = W / 2;
  if (oy >= Ho) return;
  const long base = ((long)nc * H + 2 * oy) * W;
  __global const float* r0 = x + base;
  __global const float* r1 = r0 + W;
  __global float* d0 = dx + base;
  __global float* d1 = d0 + W;
  __global const float* g = dy + ((long)nc * Ho + oy) * Wo;
  int ox = 0;
  for (; ox + 8 <= Wo; ox += 8) {
    const float8 a0 = vload8(0, r0 + 2 * ox), a1 = vload8(0, r0 + 2 * ox + 8);
    const float8 b0 = vload8(0, r1 + 2 * ox), b1 = vload8(0, r1 + 2 * ox + 8);
    const float8 v00 = (float8)(a0.even, a1.even), v01 = (float8)(a0.odd, a1.odd);
    const float8 v10 = (float8)(b0.even, b1.even), v11 = (float8)(b0.odd, b1.odd);
    const float8 gv = vload8(0, g + ox);
    const float8 m = fmax(fmax(v00, v01), fmax(v10, v11));
    // First-maximum masks (comparisons give -1 for true in vector form).
    const int8 is00 = v00 == m;
    const int8 is01 = (v01 == m) & ~is00;
    const int8 is10 = (v10 == m) & ~is00 & ~is01;
    const int8 is11 = ~is00 & ~is01 & ~is10;
    const float8 z = (float8)(0.0f);
    const float8 g00 = select(z, gv, is00), g01 = select(z, gv, is01);
    const float8 g10 = select(z, gv, is10), g11 = select(z, gv, is11);
    vstore8(shuffle2(g00, g01, ZIP_LO), 0, d0 + 2 * ox);
    vstore8(shuffle2(g00, g01, ZIP_HI), 0, d0 + 2 * ox + 8);
    vstore8(shuffle2(g10, g11, ZIP_LO), 0, d1 + 2 * ox);
    vstore8(shuffle2(g10, g11, ZIP_HI), 0, d1 + 2 * ox + 8);
  }
  for (; ox < Wo; ++ox) {
    const float v[4] = {r0[2 * ox], r0[2 * ox + 1], r1[2 * ox], r1[2 * ox + 1]};
    int best = 0;
    for (int j = 1; j < 4; ++j)
      if (v[j] > v[best]) best = j;
    d0[2 * ox] = best == 0 ? g[ox] : 0.0f;
    d0[2 * ox + 1] = best == 1 ? g[ox] : 0.0f;
    d1[2 * ox] = best == 2 ? g[ox] : 0.0f;
    d1[2 * ox + 1] = best == 3 ? g[ox] : 0.0f;
  }
}

// ---- x2 nearest-neighbour upsampling -----------------------------------------------------------
// One work-item per input row (n, c, iy), writing output rows 2*iy and 2*iy+1. Global: (H, N * C).
__kernel void upsample2x_forward(__global const float* x, __global float* y, int H, int W) {
  const int iy = get_global_id(0);
  const int nc = get_global_id(1);
  if (iy >= H) return;
  __global const float* src = x + ((long)nc * H + iy) * W;
  __global float* o0 = y + ((long)nc * 2 * H + 2 * iy) * (2 * W);
  __global float* o1 = o0 + 2 * W;
  int ix = 0;
  for (; ix + 8 <= W; ix += 8) {
    const float8 v = vload8(0, src + ix);
    const float8 lo = shuffle2(v, v, ZIP_LO), hi = shuffle2(v, v, ZIP_HI);
    vstore8(lo, 0, o0 + 2 * ix);
    vstore8(hi, 0, o0 + 2 * ix + 8);
    vstore8(lo, 0, o1 + 2 * ix);
    vstore8(hi, 0, o1 + 2 * ix + 8);
  }
  for (; ix < W; ++ix) {
    const float v = src[ix];
    o0[2 * ix] = o0[2 * ix + 1] = o1[2 * ix] = o1[2 * ix + 1] = v;
  }
}

// dx[iy, ix] = sum of the 2x2 block of dy it was copied to. Global: (H, N * C), H, W of dx.
__kernel void upsample2x_backward(__global const float* dy, __global float* dx, int H, int W) {
  const int iy = get_global_id(0);
  const int nc = get_global_id(1);
  if (iy >= H) return;
  __global const float* g0 = dy + ((long)nc * 2 * H + 2 * iy) * (2 * W);
  __global const float* g1 = g0 + 2 * W;
  __global float* dst = dx + ((long)nc * H + iy) * W;
  int ix = 0;
  for (; ix + 8 <= W; ix += 8) {
    const float8 s0 = vload8(0, g0 + 2 * ix) + vload8(0, g1 + 2 * ix);
    const float8 s1 = vload8(0, g0 + 2 * ix + 8) + vload8(0, g1 + 2 * ix + 8);
    vstore8((float8)(s0.even + s0.odd, s1.even + s1.odd), 0, dst + ix);
  }
  for (; ix < W; ++ix) dst[ix] = (g0[2 * ix] + g0[2 * ix + 1]) + (g1[2 * ix] + g1[2 * ix + 1]);
}

// ---- polyphase ("a trous") 2x2 max pooling and its interleave --------------------------------------
// A stride-2 pool fixes a 2-pixel grid to the image; its four phases, one per offset (a, b) in {0,1}^2,
// together are a stride-1 pool. Stacked as batch blocks (block 2a + b holds phase (a, b)), the layers
// after the pool run on each phase as on an ordinary image, and phase_interleave puts the phases back
// side by side, where a nearest upsampling would have repeated one of them. The result moves with its
// input by one pixel of the pooled-from map instead of two (lib/nn/ops.hpp).

// y[(2a+b)*N + n, c, i, j] = max over r, s in {0,1} of x[n, c, min(2i+a+r, H-1), min(2j+b+s, W-1)].
// Global: (Ho * Wo, 4 * N * C), H and W even.
__kernel void maxpool2x2_phases_forward(__global const float* x, __global float* y, int NC, int H, int W) {
  const int idx = get_global_id(0);
  const int pc = get_global_id(1);
  const int Ho = H / 2, Wo = W / 2;
  if (idx >= Ho * Wo) return;
  const int phase = pc / NC, nc = pc - phase * NC;
  const int y0 = 2 * (idx / Wo) + (phase >> 1), x0 = 2 * (idx % Wo) + (phase & 1);
  const int y1 = min(y0 + 1, H - 1), x1 = min(x0 + 1, W - 1);
  __global const float* p = x + (long)nc * H * W;
  y[(long)pc * Ho * Wo + idx] = fmax(fmax(p[y0 * W + x0], p[y0 * W + x1]), fmax(p[y1 * W + x0], p[y1 * W + x1]));
}

// dx[n, c, y, x] = the sum of dy over the windows whose first maximum (order (0,0), (0,1), (1,0), (1,1),
// as maxpool2x2_backward) is (y, x). A pixel lies in the windows starting at (y-1|y, x-1|x); a clamped
// window at the last row / column counts its repeated pixel once. Every dx element is written.
// Global: (H * W, N * C).
__kernel void maxpool2x2_phases_backward(__global const float* x, __global const float* dy, __global float* dx,
                                         int NC, int H, int W) {
  const int idx = get_global_id(0);
  const int nc = get_global_id(1);
  if (idx >= H * W) return;
  const int py = idx / W, px = idx - py * W;
  const int Ho = H / 2, Wo = W / 2;
  __global const float* p = x + (long)nc * H * W;
  float sum = 0.0f;
  for (int oy = max(py - 1, 0); oy <= py; ++oy)
    for (int ox = max(px - 1, 0); ox <= px; ++ox) {
      const int y1 = min(oy + 1, H - 1), x1 = min(ox + 1, W - 1);
      const float v00 = p[oy * W + ox], v01 = p[oy * W + x1], v10 = p[y1 * W + ox], v11 = p[y1 * W + x1];
      const float m = fmax(fmax(v00, v01), fmax(v10, v11));
      const int ay = (v00 == m || v01 == m) ? oy : y1;
      const int ax = v00 == m ? ox : v01 == m ? x1 : v10 == m ? ox : x1;
      if (ay != py || ax != px) continue;
      const int phase = (oy & 1) * 2 + (ox & 1);
      sum += dy[((long)phase * NC + nc) * Ho * Wo + (oy >> 1) * Wo + (ox >> 1)];
    }
  dx[(long)nc * H * W + idx] = sum;
}

// y[n, c, 2i+a, 2j+b] = x[(2a+b)*N + n, c, i, j]: x [4N, C, h, w] -> y [N, C, 2h, 2w]. Global: (4hw, N*C).
__kernel void phase_interleave_forward(__global const float* x, __global float* y, int NC, int h, int w) {
  const int idx = get_global_id(0);
  const int nc = get_global_id(1);
  if (idx >= 4 * h * w) return;
  const int Y = idx / (2 * w), X = idx - Y * (2 * w);
  const int phase = (Y & 1) * 2 + (X & 1);
  y[(long)nc * 4 * h * w + idx] = x[((long)phase * NC + nc) * h * w + (Y >> 1) * w + (X >> 1)];
}

// Its transpose (a permutation): dx[(2a+b)*N + n, c, i, j] = dy[n, c, 2i+a, 2j+b]. Global: (hw, 4*N*C).
__kernel void phase_interleave_backward(__global const float* dy, __global float* dx, int NC, int h, int w) {
  const int idx = get_global_id(0);
  const int pc = get_global_id(1);
  if (idx >= h * w) return;
  const int phase = pc / NC, nc = pc - phase * NC;
  const int Y = 2 * (idx / w) + (phase >> 1), X = 2 * (idx % w) + (phase & 1);
  dx[(long)pc * h * w + idx] = dy[(long)nc * 4 * h * w + Y * 2 * w + X];
}
