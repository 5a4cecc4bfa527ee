// Winograd F(m x m, 3 x 3) convolution (Lavin & Gray 2016) for the stride-1 "same" 3x3 convs, with the
// exact adjoints of every transform so that dX and dW run in the transformed domain too:
//
//   forward   U = G g G^T (per filter), V = B^T d B (per input tile), M = U . V summed over input
//             channels (alpha^2 GEMMs, lib/nn/conv_winograd.cpp), Y = A^T M A (per output tile)
//   backward  dM = A dY A^T, dV = U^T dM and dU = dM V^T (GEMMs), dd = B dV B^T, dg = G^T dU G
//
// Built with -DWINO_M=2 (alpha = 4, 16 GEMMs, 2.25x fewer multiplies than direct) or -DWINO_M=4
// (alpha = 6, 36 GEMMs, 4x fewer, larger rounding error: its transforms have entries up to 8 and 1/24).
//
// Layouts (row-major): U / dU [alpha^2][Cout][Cin]; V / dV [alpha^2][C][T]; M / dM [alpha^2][Cout][T],
// where T = N * th * tw tiles, th = ceil(H / m), tw = ceil(W / m), tile t = (n * th + ty) * tw + tx covers
// output rows ty*m .. ty*m+m-1 (those past the image are computed and dropped) and reads padded input rows
// ty*m-1 .. ty*m+m. The tile kernels give each work-item 8 consecutive tiles of one tile row and one
// channel, as float8 lanes: each of its alpha^2 values is one 8-float store into a [C][T] plane.

#ifndef WINO_M
#define WINO_M 2
#endif
#define WINO_R 3
#define WINO_A (WINO_M + WINO_R - 1)

#define PAD_ZERO 0
#define PAD_REFLECT 1

#if WINO_M != 2 && WINO_M != 4
#error "WINO_M must be 2 or 4"
#endif

// Input index of padded coordinate p (the pad is one pixel each side), or -1 where the value is zero:
// zero padding, or coordinates past the padding (read only by outputs past the image).
inline int wino_source(int p, int n, int mode) {
  if (p >= 0 && p < n) return p;
  if (mode == PAD_REFLECT && (p == -1 || p == n)) return p < 0 ? 1 : n - 2;
  return -1;
}

// ---- 1-D transforms on 8 tiles at once ---------------------------------------------------------
// The 2-D transforms apply these along columns, then rows. Written out (not matrix loops) so that only
// the non-zero entries cost anything. bt: r = B^T d; b_adj: d = B r (its adjoint); at: o = A^T v;
// a_adj: v = A o.
typedef float8 v8;
#define VEC 8

#if WINO_M == 2
inline void bt_1d(const v8* d, v8* r) {
  r[0] = d[0] - d[2];
  r[1] = d[1] + d[2];
  r[2] = d[2] - d[1];
  r[3] = d[1] - d[3];
}
inline void b_adj_1d(const v8* r, v8* d) {
  d[0] = r[0];
  d[1] = r[1] - r[2] + r[3];
  d[2] = r[1] + r[2] - r[0];
  d[3] = -r[3];
}
inline void at_1d(const v8* v, v8* o) {
  o[0] = v[0] + v[1] + v[2];
  o[1] = v[1] - v[2] - v[3];
}
// u = G g (3 -> alpha) and its adjoint g = G^T u.
inline void g_1d(const v8* g, v8* u) {
  u[0] = g[0];
  u[1] = 0.5f * (g[0] + g[1] + g[2]);
  u[2] = 0.5f * (g[0] - g[1] + g[2]);
  u[3] = g[2];
}
inline void g_adj_1d(const v8* u, v8* g) {
  g[0] = u[0] + 0.5f * (u[1] + u[2]);
  g[1] = 0.5f * (u[1] - u[2]);
  g[2] = 0.5f * (u[1] + u[2]) + u[3];
}
inline void a_adj_1d(const v8* o, v8* v) {
  v[0] = o[0];
  v[1] = o[0] + o[1];
  v[2] = o[0] - o[1];
  v[3] = -o[1];
}
#else
inline void bt_1d(const v8* d, v8* r) {
  r[0] = 4.0f * d[0] - 5.0f * d[2] + d[4];
  r[1] = d[3] + d[4] - 4.0f * (d[1] + d[2]);
  r[2] = d[4] - d[3] + 4.0f * (d[1] - d[2]);
  r[3] = d[4] - d[2] + 2.0f * (d[3] - d[1]);
  r[4] = d[4] - d[2] + 2.0f * (d[1] - d[3]);
  r[5] = 4.0f * d[1] - 5.0f * d[3] + d[5];
}
inline void b_adj_1d(const v8* r, v8* d) {
  d[0] = 4.0f * r[0];
  d[1] = 4.0f * (r[2] - r[1] + r[5]) + 2.0f * (r[4] - r[3]);
  d[2] = -5.0f * r[0] - 4.0f * (r[1] + r[2]) - r[3] - r[4];
  d[3] = r[1] - r[2] + 2.0f * (r[3] - r[4]) - 5.0f * r[5];
  d[4] = r[0] + r[1] + r[2] + r[3] + r[4];
  d[5] = r[5];
}
inline void at_1d(const v8* v, v8* o) {
  o[0] = v[0] + v[1] + v[2] + v[3] + v[4];
  o[1] = v[1] - v[2] + 2.0f * (v[3] - v[4]);
  o[2] = v[1] + v[2] + 4.0f * (v[3] + v[4]);
  o[3] = v[1] - v[2] + 8.0f * (v[3] - v[4]) + v[5];
}
inline void g_1d(const v8* g, v8* u) {
  u[0] = 0.25f * g[0];
  u[1] = -(g[0] + g[1] + g[2]) / 6.0f;
  u[2] = -(g[0] - g[1] + g[2]) / 6.0f;
  u[3] = g[0] / 24.0f + g[1] / 12.0f + g[2] / 6.0f;
  u[4] = g[0] / 24.0f - g[1] / 12.0f + g[2] / 6.0f;
  u[5] = g[2];
}
inline void g_adj_1d(const v8* u, v8* g) {
  g[0] = 0.25f * u[0] - (u[1] + u[2]) / 6.0f + (u[3] + u[4]) / 24.0f;
  g[1] = (u[2] - u[1]) / 6.0f + (u[3] - u[4]) / 12.0f;
  g[2] = -(u[1] + u[2]) / 6.0f + (u[3] + u[4]) / 6.0f + u[5];
}
inline void a_adj_1d(const v8* o, v8* v) {
  v[0] = o[0];
  v[1] = o[0] + o[1] + o[2] + o[3];
  v[2] = o[0] - o[1] + o[2] - o[3];
  v[3] = o[0] + 2.0f * o[1] + 4.0f * o[2] + 8.0f * o[3];
  v[4] = o[0] - 2.0f * o[1] + 4.0f * o[2] - 8.0f * o[3];
  v[5] = o[3];
}
#endif

// Lanes k of the 8 tiles: element j + k * m of a row segment.
inline v8 lanes(const float* seg, int j) {
  return (v8)(seg[j], seg[j + WINO_M], seg[j + 2 * WINO_M], seg[j + 3 * WINO_M], seg[j + 4 * WINO_M],
              seg[j + 5 * WINO_M], seg[j + 6 * WINO_M], seg[j + 7 * WINO_M]);
}

// Work-items cover 8 consecutive tiles of one tile row: group g of row r = n * th + ty holds tiles
// tx0 = 8 * (g % groups) .. tx0 + 7 (the last group of a row may be partial: `valid` lanes).
#define TILE_GROUP_SETUP                                      \
  const int groups = (tw + VEC - 1) / VEC;                    \
  const int gx = g % groups, trow = g / groups;               \
  const int ty = trow % th, n = trow / th;                    \
  const int tx0 = gx * VEC, valid = min(VEC, tw - tx0);       \
  const long t0 = (long)trow * tw + tx0;

inline v8 load_lanes(__global const float* p, int valid) {
  if (valid == VEC) return vload8(0, p);
  v8 v = (v8)(0.0f);
  float tmp[VEC];
  for (int k = 0; k < VEC; ++k) tmp[k] = k < valid ? p[k] : 0.0f;
  return vload8(0, tmp);
}
inline void store_lanes(v8 v, __global float* p, int valid) {
  if (valid == VEC) {
    vstore8(v, 0, p);
    return;
  }
  float tmp[VEC];
  vstore8(v, 0, tmp);
  for (int k = 0; k < valid; ++k) p[k] = tmp[k];
}

// out[.][j] = fn(in[.][j]) for each of the ncols columns: the first half of a 2-D transform (fn maps a
// column of n_in values to one of n_out; the rows then go through fn directly).
#define TRANSFORM_COLUMNS(fn, in, n_in, out, n_out, ncols) \
  for (int j_ = 0; j_ < (ncols); ++j_) {                   \
    v8 c_[WINO_A], r_[WINO_A];                              \
    for (int i_ = 0; i_ < (n_in); ++i_) c_[i_] = in[i_][j_]; \
    fn(c_, r_);                                             \
    for (int i_ = 0; i_ < (n_out); ++i_) out[i_][j_] = r_[i_]; \
  }

// ---- filters ---------------------------------------------------------------------------------
// U[xi][co][ci] = (G g G^T)[xi], g = w[co][ci] (3x3); a work-item transforms 8 consecutive input
// channels (lanes) of one filter. Global: (ceil(Cin / 8), Cout).
__kernel void wino_filter_transform(__global const float* w, __global float* U, int Cin, int Cout) {
  const int cg = get_global_id(0), co = get_global_id(1);
  const int ci0 = cg * VEC, valid = min(VEC, Cin - ci0);
  if (valid <= 0 || co >= Cout) return;
  __global const float* g = w + ((long)co * Cin + ci0) * 9;
  v8 g3[3][3], u[WINO_A], gg[WINO_A][3];
  for (int r = 0; r < 9; ++r) {
    float tmp[VEC];
    for (int k = 0; k < VEC; ++k) tmp[k] = k < valid ? g[k * 9 + r] : 0.0f;
    g3[r / 3][r % 3] = vload8(0, tmp);
  }
  TRANSFORM_COLUMNS(g_1d, g3, 3, gg, WINO_A, 3)  // G g
  const long plane = (long)Cout * Cin;
  __global float* out = U + (long)co * Cin + ci0;
  for (int i = 0; i < WINO_A; ++i) {  // (G g) G^T, row by row
    g_1d(gg[i], u);
    for (int j = 0; j < WINO_A; ++j) store_lanes(u[j], out + (i * WINO_A + j) * plane, valid);
  }
}

// The adjoint: dw[co][ci] = G^T dU[.][co][ci] G (3x3), overwritten; 8 input channels a work-item.
// Global: (ceil(Cin / 8), Cout).
__kernel void wino_filter_backward(__global const float* dU, __global float* dw, int Cin, int Cout) {
  const int cg = get_global_id(0), co = get_global_id(1);
  const int ci0 = cg * VEC, valid = min(VEC, Cin - ci0);
  if (valid <= 0 || co >= Cout) return;
  const long plane = (long)Cout * Cin;
  __global const float* p = dU + (long)co * Cin + ci0;
  v8 u[WINO_A][WINO_A], g[3], gu[3][WINO_A];
  for (int i = 0; i < WINO_A; ++i)
    for (int j = 0; j < WINO_A; ++j) u[i][j] = load_lanes(p + (i * WINO_A + j) * plane, valid);
  TRANSFORM_COLUMNS(g_adj_1d, u, WINO_A, gu, 3, WINO_A)  // G^T dU
  float taps[9][VEC];
  for (int r = 0; r < 3; ++r) {  // (G^T dU) G, row by row
    g_adj_1d(gu[r], g);
    for (int s = 0; s < 3; ++s) vstore8(g[s], 0, taps[r * 3 + s]);
  }
  __global float* out = dw + ((long)co * Cin + ci0) * 9;
  for (int k = 0; k < valid; ++k)
    for (int r = 0; r < 9; ++r) out[k * 9 + r] = taps[r][k];
}

// ---- input tiles -----------------------------------------------------------------------------
// V[xi][c][t] = (B^T d B)[xi], d = the padded alpha x alpha input patch of tile t.
// Global: (N * th * ceil(tw / 8), C).
#define SEG (VEC * WINO_M + 2)
__kernel void wino_input_transform(__global const float* x, __global float* V, int C, int H, int W, int th, int tw,
                                   int T, int mode) {
  const int g = get_global_id(0), c = get_global_id(1);
  if (g >= T / tw * ((tw + VEC - 1) / VEC) || c >= C) return;
  TILE_GROUP_SETUP
  __global const float* img = x + ((long)n * C + c) * H * W;
  const int xs = tx0 * WINO_M - 1;
  const bool inner = xs >= 0 && xs + SEG <= W;
  v8 d[WINO_A][WINO_A];
  for (int i = 0; i < WINO_A; ++i) {
    const int sy = wino_source(ty * WINO_M - 1 + i, H, mode);
    float seg[SEG];
    if (sy < 0) {
      for (int k = 0; k < SEG; ++k) seg[k] = 0.0f;
    } else if (inner) {
      __global const float* src = img + (long)sy * W + xs;
      for (int k = 0; k < SEG; ++k) seg[k] = src[k];
    } else {
      __global const float* src = img + (long)sy * W;
      for (int k = 0; k < SEG; ++k) {
        const int sx = wino_source(xs + k, W, mode);
        seg[k] = sx >= 0 ? src[sx] : 0.0f;
      }
    }
    for (int j = 0; j < WINO_A; ++j) d[i][j] = lanes(seg, j);
  }
  v8 tmp[WINO_A][WINO_A];
  TRANSFORM_COLUMNS(bt_1d, d, WINO_A, tmp, WINO_A, WINO_A)  // B^T d
  const long plane = (long)C * T;
  __global float* out = V + (long)c * T + t0;
  for (int i = 0; i < WINO_A; ++i) {  // (B^T d) B, row by row
    v8 r[WINO_A];
    bt_1d(tmp[i], r);
    for (int j = 0; j < WINO_A; ++j) store_lanes(r[j], out + (i * WINO_A + j) * plane, valid);
  }
}

// The adjoint, step 1: dV[.][c][t] becomes dd = B dV B^T in place (each work-item owns its values).
// Global: (N * th * ceil(tw / 8), C).
__kernel void wino_input_backward(__global float* dV, int C, int th, int tw, int T) {
  const int g = get_global_id(0), c = get_global_id(1);
  if (g >= T / tw * ((tw + VEC - 1) / VEC) || c >= C) return;
  TILE_GROUP_SETUP
  const long plane = (long)C * T;
  __global float* p = dV + (long)c * T + t0;
  v8 v[WINO_A][WINO_A], tmp[WINO_A][WINO_A];
  for (int i = 0; i < WINO_A; ++i)
    for (int j = 0; j < WINO_A; ++j) v[i][j] = load_lanes(p + (i * WINO_A + j) * plane, valid);
  TRANSFORM_COLUMNS(b_adj_1d, v, WINO_A, tmp, WINO_A, WINO_A)  // B dV
  for (int i = 0; i < WINO_A; ++i) {
    v8 r[WINO_A];
    b_adj_1d(tmp[i], r);
    for (int j = 0; j < WINO_A; ++j) store_lanes(r[j], p + (i * WINO_A + j) * plane, valid);
  }
}

// Step 2: dx = the sum, over the tiles whose patch covers a pixel, of their dd there. Pixel row a of the
// m x m block under tile (ty, tx) lies in tile ty (patch row a + 1), in tile ty + 1 when a = m - 1 (row 0)
// and in tile ty - 1 when a = 0 (row m + 1); columns likewise. A work-item gathers the blocks under 8
// tiles of a tile row: each term is one float8 load of 8 neighbouring tiles' values. Overwrites dx; the
// mirror rows / columns of reflect padding are added by wino_input_gather_reflect after it.
// Global: (N * th * ceil(tw / 8), C).
inline v8 load_shifted(__global const float* p, int dtx, int tx0, int valid, int tw) {
  if (valid == VEC && tx0 + dtx >= 0 && tx0 + dtx + VEC <= tw) return vload8(0, p + dtx);
  float tmp[VEC];
  for (int k = 0; k < VEC; ++k) {
    const int tx = tx0 + k + dtx;
    tmp[k] = (k < valid && tx >= 0 && tx < tw) ? p[k + dtx] : 0.0f;
  }
  return vload8(0, tmp);
}

__kernel void wino_input_gather(__global const float* dd, __global float* dx, int C, int H, int W, int th, int tw,
                                int T) {
  const int g = get_global_id(0), c = get_global_id(1);
  if (g >= T / tw * ((tw + VEC - 1) / VEC) || c >= C) return;
  TILE_GROUP_SETUP
  const long plane = (long)C * T;
  __global const float* tiles = dd + (long)c * T + t0;
  __global float* img = dx + ((long)n * C + c) * H * W;
  const int x0 = tx0 * WINO_M, xn = min(VEC * WINO_M, W - x0);
  for (int a = 0; a < WINO_M; ++a) {
    const int oy = ty * WINO_M + a;
    if (oy >= H) break;
    // (tile row offset, patch row) of each tile covering this pixel row.
    int dty[3], pi[3], nr = 0;
    dty[nr] = 0, pi[nr++] = a + 1;
    if (a == WINO_M - 1 && ty + 1 < th) dty[nr] = 1, pi[nr++] = 0;
    if (a == 0 && ty >= 1) dty[nr] = -1, pi[nr++] = WINO_M + 1;
    float row[VEC * WINO_M], lane[VEC];
    for (int b = 0; b < WINO_M; ++b) {
      int dtx[3], pj[3], nc = 0;
      dtx[nc] = 0, pj[nc++] = b + 1;
      if (b == WINO_M - 1) dtx[nc] = 1, pj[nc++] = 0;
      if (b == 0) dtx[nc] = -1, pj[nc++] = WINO_M + 1;
      v8 acc = (v8)(0.0f);
      for (int r = 0; r < nr; ++r)
        for (int q = 0; q < nc; ++q)
          acc += load_shifted(tiles + (pi[r] * WINO_A + pj[q]) * plane + (long)dty[r] * tw, dtx[q], tx0, valid, tw);
      vstore8(acc, 0, lane);
      for (int k = 0; k < VEC; ++k) row[k * WINO_M + b] = lane[k];
    }
    __global float* dst = img + (long)oy * W + x0;
    for (int k = 0; k < xn; ++k) dst[k] = row[k];
  }
}

// Sum over the tiles covering padded coordinate (p, q) of their dd at that coordinate.
inline float wino_gather_point(__global const float* dd, long plane, long cbase, int p, int q, int n, int th, int tw) {
  // Tile ty reads padded rows ty*m-1 .. ty*m+m. The lower bounds divide numbers >= -2; C's rounding
  // towards zero can only raise a negative bound to 0, which max() gives anyway.
  const int ty_lo = max(0, (p - 1) / WINO_M), ty_hi = min(th - 1, (p + 1) / WINO_M);
  const int tx_lo = max(0, (q - 1) / WINO_M), tx_hi = min(tw - 1, (q + 1) / WINO_M);
  float acc = 0.0f;
  for (int ty = ty_lo; ty <= ty_hi; ++ty)
    for (int tx = tx_lo; tx <= tx_hi; ++tx) {
      const int i = p - (ty * WINO_M - 1), j = q - (tx * WINO_M - 1);
      if (i < 0 || i >= WINO_A || j < 0 || j >= WINO_A) continue;
      acc += dd[(i * WINO_A + j) * plane + cbase + (long)(n * th + ty) * tw + tx];
    }
  return acc;
}

// Reflect padding only, after wino_input_gather: the padded coordinates -1 and H (W) copy rows 1 and H-2
// (columns 1 and W-2), so those pixels also collect the tiles' dd at the mirror coordinates. Work-item
// (i, side, n*C + c): side 0 / 1 walk rows 1 and H-2 (i = x), sides 2 / 3 columns 1 and W-2 (i = y, rows
// already walked skipped), so each pixel is visited once.
__kernel void wino_input_gather_reflect(__global const float* dd, __global float* dx, int C, int H, int W, int th,
                                        int tw, int N) {
  const int i = get_global_id(0), side = get_global_id(1), nc = get_global_id(2);
  if (side >= 4 || nc >= N * C) return;
  const bool row_side = side < 2;
  if (i >= (row_side ? W : H)) return;
  int y, x;
  if (row_side) {
    y = side == 0 ? 1 : H - 2;
    x = i;
    if (side == 1 && y == 1) return;  // H = 3: one row
  } else {
    x = side == 2 ? 1 : W - 2;
    y = i;
    if (side == 3 && x == 1) return;
    if (y == 1 || y == H - 2) return;  // done by a row side
  }
  const int n = nc / C, c = nc % C;
  const long T = (long)N * th * tw, plane = (long)C * T, cbase = (long)c * T;
  int ps[3], qs[3], np = 0, nq = 0;
  ps[np++] = y;
  qs[nq++] = x;
  if (y == 1) ps[np++] = -1;
  if (y == H - 2) ps[np++] = H;
  if (x == 1) qs[nq++] = -1;
  if (x == W - 2) qs[nq++] = W;
  float acc = 0.0f;
  for (int a = 0; a < np; ++a)
    for (int b = 0; b < nq; ++b)
      if (a > 0 || b > 0) acc += wino_gather_point(dd, plane, cbase, ps[a], qs[b], n, th, tw);
  dx[(((long)n * C + c) * H + y) * W + x] += acc;
}

// ---- output tiles ----------------------------------------------------------------------------
// y[n][co][ty*m + i][tx*m + j] = (A^T M A)[i][j] (+ bias[co]) for the outputs inside the image.
// has_bias = 0: bias is not read. Global: (N * th * ceil(tw / 8), Cout).
__kernel void wino_output_transform(__global const float* M, __global const float* bias, int has_bias,
                                    __global float* y, int Cout, int H, int W, int th, int tw, int T) {
  const int g = get_global_id(0), co = get_global_id(1);
  if (g >= T / tw * ((tw + VEC - 1) / VEC) || co >= Cout) return;
  TILE_GROUP_SETUP
  const long plane = (long)Cout * T;
  __global const float* p = M + (long)co * T + t0;
  v8 v[WINO_A][WINO_A], tmp[WINO_M][WINO_A];
  for (int i = 0; i < WINO_A; ++i)
    for (int j = 0; j < WINO_A; ++j) v[i][j] = load_lanes(p + (i * WINO_A + j) * plane, valid);
  TRANSFORM_COLUMNS(at_1d, v, WINO_A, tmp, WINO_M, WINO_A)  // A^T M
  const float b = has_bias ? bias[co] : 0.0f;
  __global float* img = y + ((long)n * Cout + co) * H * W;
  const int x0 = tx0 * WINO_M;
  const int xn = min(VEC * WINO_M, W - x0);  // columns inside the image
  for (int i = 0; i < WINO_M; ++i) {
    const int oy = ty * WINO_M + i;
    if (oy >= H) break;
    v8 o[WINO_M];
    at_1d(tmp[i], o);
    float row[VEC * WINO_M], lane[VEC];
    for (int j = 0; j < WINO_M; ++j) {
      vstore8(o[j] + b, 0, lane);
      for (int k = 0; k < VEC; ++k) row[k * WINO_M + j] = lane[k];
    }
    __global float* dst = img + (long)oy * W + x0;
    for (int k = 0; k < xn; ++k) dst[k] = row[k];
  }
}

// The adjoint: dM[.][co][t] = A dY A^T, dY the tile's m x m output gradient (zero past the image).
// Global: (N * th * ceil(tw / 8), Cout).
__kernel void wino_output_backward(__global const float* dy, __global float* dM, int Cout, int H, int W, int th,
                                   int tw, int T) {
  const int g = get_global_id(0), co = get_global_id(1);
  if (g >= T / tw * ((tw + VEC - 1) / VEC) || co >= Cout) return;
  TILE_GROUP_SETUP
  __global const float* img = dy + ((long)n * Cout + co) * H * W;
  const int x0 = tx0 * WINO_M;
  const int xn = min(VEC * WINO_M, W - x0);
  v8 d[WINO_M][WINO_M];
  for (int i = 0; i < WINO_M; ++i) {
    const int oy = ty * WINO_M + i;
    float row[VEC * WINO_M];
    for (int k = 0; k < VEC * WINO_M; ++k) row[k] = 0.0f;
    if (oy < H) {
      __global const float* src = img + (long)oy * W + x0;
      for (int k = 0; k < xn; ++k) row[k] = src[k];
    }
    for (int j = 0; j < WINO_M; ++j) d[i][j] = lanes(row, j);
  }
  v8 tmp[WINO_A][WINO_M];
  TRANSFORM_COLUMNS(a_adj_1d, d, WINO_M, tmp, WINO_A, WINO_M)  // A dY
  const long plane = (long)Cout * T;
  __global float* out = dM + (long)co * T + t0;
  for (int i = 0; i < WINO_A; ++i) {  // (A dY) A^T, row by row
    v8 v[WINO_A];
    a_adj_1d(tmp[i], v);
    for (int j = 0; j < WINO_A; ++j) store_lanes(v[j], out + (i * WINO_A + j) * plane, valid);
  }
}
