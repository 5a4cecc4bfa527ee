// Layout ops: a dense 2-D transpose, dst[c, r] = src[r, c] for src [rows, cols] and dst [cols, rows]; and
// copies of column blocks between row-major matrices (copy_columns, at the end).
//
// lib/nn/layout.cpp builds both directions of [R,C] rows <-> [1,C,H,W] image on it: rows_to_image
// transposes [H*W, C] into [C, H*W]; image_to_rows is the reverse transpose. Each is the other's
// backward, so this one kernel is forward and backward of both.
//
// On PoCL/CPU (docs/design.md: barriers are costly, vectorise inside a work-item) a work-item transposes a
// 16x16 tile in registers, as four 8x8 blocks: it reads 16 source rows of 16 floats and writes 16
// destination rows of 16 floats, whole 64-byte cache lines on both sides, with no local memory and no
// barrier. An 8x8 block is transposed by three rounds of interleaving (zip) pairs of rows i and i+4:
// one round moves element (row i, lane j) to (row [i1 i0 j2], lane [j1 j0 i2]) in bits, a rotation of
// the 6-bit address (i, j) by one bit, so three rounds give (j, i). Tiles that cross the edge of the
// matrix take a scalar path. float8, not float16: PoCL's CPU target here has no AVX-512 (see nn.cl).

#define TILE 16

// Interleaving masks for shuffle2: (a0 b0 a1 b1 a2 b2 a3 b3) and (a4 b4 ... a7 b7).
#define ZIP_LO (uint8)(0, 8, 1, 9, 2, 10, 3, 11)
#define ZIP_HI (uint8)(4, 12, 5, 13, 6, 14, 7, 15)

// One zip round over the 8 rows in v (in place).
inline void zip_round(float8 v[8]) {
  float8 w[8];
  for (int i = 0; i < 4; ++i) {
    w[2 * i] = shuffle2(v[i], v[i + 4], ZIP_LO);
    w[2 * i + 1] = shuffle2(v[i], v[i + 4], ZIP_HI);
  }
  for (int i = 0; i < 8; ++i) v[i] = w[i];
}

// The 8x8 block at src[r0.., c0..] (row stride ld_src) to dst[c0.., r0..] (row stride ld_dst).
inline void transpose_8x8(__global const float* src, int ld_src, __global float* dst, int ld_dst) {
  float8 v[8];
  for (int i = 0; i < 8; ++i) v[i] = vload8(0, src + (long)i * ld_src);
  zip_round(v);
  zip_round(v);
  zip_round(v);
  for (int i = 0; i < 8; ++i) vstore8(v[i], 0, dst + (long)i * ld_dst);
}

// src [rows, cols] at src_off -> dst [cols, rows] at dst_off. Global: (ceil(rows/16), ceil(cols/16));
// work-item (tr, tc) owns source rows [16 tr, 16 tr + 16) and columns [16 tc, 16 tc + 16). Consecutive
// work-items in dimension 0 walk down the source, so together they fill consecutive destination lines.
__kernel void transpose2d(__global const float* src, int src_off, __global float* dst, int dst_off, int rows,
                          int cols) {
  const int r0 = get_global_id(0) * TILE, c0 = get_global_id(1) * TILE;
  if (r0 >= rows || c0 >= cols) return;
  __global const float* s = src + src_off;
  __global float* d = dst + dst_off;
  if (r0 + TILE <= rows && c0 + TILE <= cols) {
    for (int br = 0; br < TILE; br += 8)
      for (int bc = 0; bc < TILE; bc += 8)
        transpose_8x8(s + (long)(r0 + br) * cols + c0 + bc, cols, d + (long)(c0 + bc) * rows + r0 + br, rows);
    return;
  }
  // Edge tile: element by element, destination-row order.
  const int re = min(r0 + TILE, rows), ce = min(c0 + TILE, cols);
  for (int c = c0; c < ce; ++c)
    for (int r = r0; r < re; ++r) d[(long)c * rows + r] = s[(long)r * cols + c];
}

// Column blocks: dst[r, dst_col + j] = src[r, src_col + j] for j < n, rows of ld_src / ld_dst floats.
// Global: (ceil(n / 8), rows); a work-item copies 8 consecutive floats of one row.
__kernel void copy_columns(__global const float* src, int ld_src, int src_col, __global float* dst, int ld_dst,
                           int dst_col, int n, int rows) {
  const int j0 = get_global_id(0) * 8, r = get_global_id(1);
  if (r >= rows) return;
  __global const float* s = src + (long)r * ld_src + src_col;
  __global float* d = dst + (long)r * ld_dst + dst_col;
  const int je = min(j0 + 8, n);
  for (int j = j0; j < je; ++j) d[j] = s[j];
}
