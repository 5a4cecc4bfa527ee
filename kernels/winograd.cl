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
// ty*m-1 .. ty*m+m. One work-item per (tile, channel), tiles along dimension 0 so that neighbouring
// work-items write neighbouring elements of each [C][T] plane.

#ifndef WINO_M
#define WINO_M 2
#endif
#define WINO_R 3
#define WINO_A (WINO_M + WINO_R - 1)

#define PAD_ZERO 0
#define PAD_REFLECT 1

#if WINO_M == 2
__constant float BT[4][4] = {{1, 0, -1, 0}, {0, 1, 1, 0}, {0, -1, 1, 0}, {0, 1, 0, -1}};
__constant float G[4][3] = {{1, 0, 0}, {0.5f, 0.5f, 0.5f}, {0.5f, -0.5f, 0.5f}, {0, 0, 1}};
__constant float AT[2][4] = {{1, 1, 1, 0}, {0, 1, -1, -1}};
#elif WINO_M == 4
// Interpolation points 0, 1, -1, 2, -2 and infinity.
__constant float BT[6][6] = {{4, 0, -5, 0, 1, 0},  {0, -4, -4, 1, 1, 0}, {0, 4, -4, -1, 1, 0},
                             {0, -2, -1, 2, 1, 0}, {0, 2, -1, -2, 1, 0}, {0, 4, 0, -5, 0, 1}};
__constant float G[6][3] = {{0.25f, 0, 0},
                            {-1.0f / 6, -1.0f / 6, -1.0f / 6},
                            {-1.0f / 6, 1.0f / 6, -1.0f / 6},
                            {1.0f / 24, 1.0f / 12, 1.0f / 6},
                            {1.0f / 24, -1.0f / 12, 1.0f / 6},
                            {0, 0, 1}};
__constant float AT[4][6] = {{1, 1, 1, 1, 1, 0}, {0, 1, -1, 2, -2, 0}, {0, 1, 1, 4, 4, 0}, {0, 1, -1, 8, -8, 1}};
#else
#error "WINO_M must be 2 or 4"
#endif

// Input index of padded coordinate p (the pad is one pixel each side), or -1 where the value is zero:
// zero padding, or coordinates past the padding (read only by outputs past the image).
inline int wino_source(int p, int n, int mode) {
  if (p >= 0 && p < n) return p;
  if (mode == PAD_REFLECT && (p == -1 || p == n)) return p < 0 ? 1 : n - 2;
  return -1;
}

// ---- filters ---------------------------------------------------------------------------------
// U[xi][co][ci] = (G g G^T)[xi], g = w[co][ci] (3x3). Global: (Cin, Cout).
__kernel void wino_filter_transform(__global const float* w, __global float* U, int Cin, int Cout) {
  const int ci = get_global_id(0), co = get_global_id(1);
  if (ci >= Cin || co >= Cout) return;
  __global const float* g = w + ((long)co * Cin + ci) * 9;
  float Gg[WINO_A][3];
  for (int i = 0; i < WINO_A; ++i)
    for (int j = 0; j < 3; ++j) Gg[i][j] = G[i][0] * g[j] + G[i][1] * g[3 + j] + G[i][2] * g[6 + j];
  const long plane = (long)Cout * Cin, at = (long)co * Cin + ci;
  for (int i = 0; i < WINO_A; ++i)
    for (int j = 0; j < WINO_A; ++j)
      U[(i * WINO_A + j) * plane + at] = Gg[i][0] * G[j][0] + Gg[i][1] * G[j][1] + Gg[i][2] * G[j][2];
}

// The adjoint: dw[co][ci] = G^T dU[.][co][ci] G (3x3), overwritten. Global: (Cin, Cout).
__kernel void wino_filter_backward(__global const float* dU, __global float* dw, int Cin, int Cout) {
  const int ci = get_global_id(0), co = get_global_id(1);
  if (ci >= Cin || co >= Cout) return;
  const long plane = (long)Cout * Cin, at = (long)co * Cin + ci;
  float t[3][WINO_A];  // G^T dU
  for (int r = 0; r < 3; ++r)
    for (int j = 0; j < WINO_A; ++j) t[r][j] = 0.0f;
  for (int i = 0; i < WINO_A; ++i)
    for (int j = 0; j < WINO_A; ++j) {
      const float v = dU[(i * WINO_A + j) * plane + at];
      for (int r = 0; r < 3; ++r) t[r][j] += G[i][r] * v;
    }
  __global float* g = dw + at * 9;
  for (int r = 0; r < 3; ++r)
    for (int s = 0; s < 3; ++s) {
      float acc = 0.0f;
      for (int j = 0; j < WINO_A; ++j) acc += t[r][j] * G[j][s];
      g[r * 3 + s] = acc;
    }
}

// ---- input tiles -----------------------------------------------------------------------------
// V[xi][c][t] = (B^T d B)[xi], d = the padded alpha x alpha input patch of tile t. Global: (T, C).
__kernel void wino_input_transform(__global const float* x, __global float* V, int C, int H, int W, int th, int tw,
                                   int T, int mode) {
  const int t = get_global_id(0), c = get_global_id(1);
  if (t >= T || c >= C) return;
  const int tx = t % tw, ty = (t / tw) % th, n = t / (tw * th);
  __global const float* img = x + ((long)n * C + c) * H * W;
  int sx[WINO_A];
  for (int j = 0; j < WINO_A; ++j) sx[j] = wino_source(tx * WINO_M - 1 + j, W, mode);
  float d[WINO_A][WINO_A];
  for (int i = 0; i < WINO_A; ++i) {
    const int sy = wino_source(ty * WINO_M - 1 + i, H, mode);
    for (int j = 0; j < WINO_A; ++j) d[i][j] = (sy >= 0 && sx[j] >= 0) ? img[(long)sy * W + sx[j]] : 0.0f;
  }
  float bd[WINO_A][WINO_A];  // B^T d
  for (int i = 0; i < WINO_A; ++i)
    for (int j = 0; j < WINO_A; ++j) {
      float acc = 0.0f;
      for (int k = 0; k < WINO_A; ++k) acc += BT[i][k] * d[k][j];
      bd[i][j] = acc;
    }
  const long plane = (long)C * T, at = (long)c * T + t;
  for (int i = 0; i < WINO_A; ++i)
    for (int j = 0; j < WINO_A; ++j) {
      float acc = 0.0f;
      for (int k = 0; k < WINO_A; ++k) acc += bd[i][k] * BT[j][k];
      V[(i * WINO_A + j) * plane + at] = acc;
    }
}

// The adjoint, step 1: dV[.][c][t] becomes dd = B dV B^T in place (each work-item owns its alpha^2
// values). Global: (T, C).
__kernel void wino_input_backward(__global float* dV, int C, int T) {
  const int t = get_global_id(0), c = get_global_id(1);
  if (t >= T || c >= C) return;
  const long plane = (long)C * T, at = (long)c * T + t;
  float v[WINO_A][WINO_A], bv[WINO_A][WINO_A];
  for (int i = 0; i < WINO_A; ++i)
    for (int j = 0; j < WINO_A; ++j) v[i][j] = dV[(i * WINO_A + j) * plane + at];
  for (int i = 0; i < WINO_A; ++i)  // B dV: row i of B is column i of B^T
    for (int j = 0; j < WINO_A; ++j) {
      float acc = 0.0f;
      for (int k = 0; k < WINO_A; ++k) acc += BT[k][i] * v[k][j];
      bv[i][j] = acc;
    }
  for (int i = 0; i < WINO_A; ++i)
    for (int j = 0; j < WINO_A; ++j) {
      float acc = 0.0f;
      for (int k = 0; k < WINO_A; ++k) acc += bv[i][k] * BT[k][j];
      dV[(i * WINO_A + j) * plane + at] = acc;
    }
}

// Sum over the tiles covering padded coordinate (p, q) of their dd at that coordinate.
inline float wino_gather_point(__global const float* dd, long plane, long cbase, int p, int q, int n, int th, int tw) {
  // Tile ty reads padded rows ty*m-1 .. ty*m-1+alpha-1.
  const int ty_lo = max(0, (p + 1 - (WINO_A - 1) + WINO_M - 1) / WINO_M), ty_hi = min(th - 1, (p + 1) / WINO_M);
  const int tx_lo = max(0, (q + 1 - (WINO_A - 1) + WINO_M - 1) / WINO_M), tx_hi = min(tw - 1, (q + 1) / WINO_M);
  float acc = 0.0f;
  for (int ty = ty_lo; ty <= ty_hi; ++ty)
    for (int tx = tx_lo; tx <= tx_hi; ++tx) {
      const int i = p - (ty * WINO_M - 1), j = q - (tx * WINO_M - 1);
      acc += dd[(i * WINO_A + j) * plane + cbase + (long)(n * th + ty) * tw + tx];
    }
  return acc;
}

// Step 2: dx[n][c][y][x] = the sum over every padded coordinate that reads x[y][x] (the pixel itself and,
// with reflect padding, the mirror row / column that copies it) of wino_gather_point. Overwrites dx.
// Global: (W, H, N * C). p + 1 >= 0 always, so the integer divisions above round as floor.
__kernel void wino_input_gather(__global const float* dd, __global float* dx, int C, int H, int W, int th, int tw,
                                int N, int mode) {
  const int x = get_global_id(0), y = get_global_id(1), nc = get_global_id(2);
  if (x >= W || y >= H || nc >= N * C) return;
  const int n = nc / C, c = nc % C;
  const long T = (long)N * th * tw, plane = (long)C * T, cbase = (long)c * T;
  int ps[3], qs[3], np = 0, nq = 0;
  ps[np++] = y;
  qs[nq++] = x;
  if (mode == PAD_REFLECT) {
    if (y == 1) ps[np++] = -1;
    if (y == H - 2) ps[np++] = H;
    if (x == 1) qs[nq++] = -1;
    if (x == W - 2) qs[nq++] = W;
  }
  float acc = 0.0f;
  for (int a = 0; a < np; ++a)
    for (int b = 0; b < nq; ++b) acc += wino_gather_point(dd, plane, cbase, ps[a], qs[b], n, th, tw);
  dx[(((long)n * C + c) * H + y) * W + x] = acc;
}

// ---- output tiles ----------------------------------------------------------------------------
// y[n][co][ty*m + i][tx*m + j] = (A^T M A)[i][j] (+ bias[co]) for the outputs inside the image.
// has_bias = 0: bias is not read. Global: (T, Cout).
__kernel void wino_output_transform(__global const float* M, __global const float* bias, int has_bias,
                                    __global float* y, int Cout, int H, int W, int th, int tw, int T) {
  const int t = get_global_id(0), co = get_global_id(1);
  if (t >= T || co >= Cout) return;
  const int tx = t % tw, ty = (t / tw) % th, n = t / (tw * th);
  const long plane = (long)Cout * T, at = (long)co * T + t;
  float m[WINO_A][WINO_A], am[WINO_M][WINO_A];
  for (int i = 0; i < WINO_A; ++i)
    for (int j = 0; j < WINO_A; ++j) m[i][j] = M[(i * WINO_A + j) * plane + at];
  for (int i = 0; i < WINO_M; ++i)
    for (int j = 0; j < WINO_A; ++j) {
      float acc = 0.0f;
      for (int k = 0; k < WINO_A; ++k) acc += AT[i][k] * m[k][j];
      am[i][j] = acc;
    }
  const float b = has_bias ? bias[co] : 0.0f;
  __global float* out = y + ((long)n * Cout + co) * H * W;
  for (int i = 0; i < WINO_M; ++i) {
    const int oy = ty * WINO_M + i;
    if (oy >= H) break;
    for (int j = 0; j < WINO_M; ++j) {
      const int ox = tx * WINO_M + j;
      if (ox >= W) break;
      float acc = 0.0f;
      for (int k = 0; k < WINO_A; ++k) acc += am[i][k] * AT[j][k];
      out[(long)oy * W + ox] = acc + b;
    }
  }
}

// The adjoint: dM[.][co][t] = A dY A^T, dY the tile's m x m output gradient (zero past the image).
// Global: (T, Cout).
__kernel void wino_output_backward(__global const float* dy, __global float* dM, int Cout, int H, int W, int th,
                                   int tw, int T) {
  const int t = get_global_id(0), co = get_global_id(1);
  if (t >= T || co >= Cout) return;
  const int tx = t % tw, ty = (t / tw) % th, n = t / (tw * th);
  __global const float* g = dy + ((long)n * Cout + co) * H * W;
  float d[WINO_M][WINO_M];
  for (int i = 0; i < WINO_M; ++i)
    for (int j = 0; j < WINO_M; ++j) {
      const int oy = ty * WINO_M + i, ox = tx * WINO_M + j;
      d[i][j] = (oy < H && ox < W) ? g[(long)oy * W + ox] : 0.0f;
    }
  float ad[WINO_A][WINO_M];  // A dY: row k of A is column k of A^T
  for (int k = 0; k < WINO_A; ++k)
    for (int j = 0; j < WINO_M; ++j) {
      float acc = 0.0f;
      for (int i = 0; i < WINO_M; ++i) acc += AT[i][k] * d[i][j];
      ad[k][j] = acc;
    }
  const long plane = (long)Cout * T, at = (long)co * T + t;
  for (int k = 0; k < WINO_A; ++k)
    for (int l = 0; l < WINO_A; ++l) {
      float acc = 0.0f;
      for (int j = 0; j < WINO_M; ++j) acc += ad[k][j] * AT[j][l];
      dM[(k * WINO_A + l) * plane + at] = acc;
    }
}
