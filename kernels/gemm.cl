// Register-tiled single-precision GEMM for CPU-like OpenCL devices (PoCL), plus the transpose used to
// pack one operand when neither operand is contiguous along an output dimension.
//
// The tile kernel computes D[P,Q] = alpha * L[P,K] R[K,Q] + beta * D on strided views:
//   L(p,k) = L[l_off + p*slp + k*slk]   (any strides: its elements are broadcast one at a time)
//   R(k,q) = R[r_off + k*srk + q]       (contiguous along q: loaded as vectors)
//   D(p,q) = C[c_off + p*scp + q*scq]
// The host maps the four row-major transpose cases onto it (see host/gemm.cpp). Each work-item owns an
// MR x (NV*VW) tile of D held in NV vectors per row; per k it loads NV vectors of R and broadcasts MR
// scalars of L into fma. On a CPU this is the classic outer-product micro-kernel: the accumulators stay
// in registers and there are no barriers or local memory (both are costly on PoCL).
//
// Build options (all optional): -DMR=rows -DVW=4|8|16 -DNV=vectors per row, -DQT=tiles along q per
// work-item (a work-item walks QT neighbouring tiles with the same L rows: fewer, longer work-items,
// which matters on PoCL where each work-group has a fixed scheduling cost and small K makes tiles short).

#ifndef MR
#define MR 6
#endif
#ifndef VW
#define VW 8
#endif
#ifndef NV
#define NV 2
#endif
#ifndef QT
#define QT 1
#endif
#define NR (VW * NV)

#if VW == 4
typedef float4 vec_t;
#define VLOAD vload4
#define VSTORE vstore4
#elif VW == 8
typedef float8 vec_t;
#define VLOAD vload8
#define VSTORE vstore8
#elif VW == 16
typedef float16 vec_t;
#define VLOAD vload16
#define VSTORE vstore16
#else
#error "VW must be 4, 8 or 16"
#endif

typedef union {
  vec_t v;
  float s[VW];
} vec_u;

// acc[i][.] += L[p0 + i][k] * b[.] for the tile's MR rows: the rank-1 update of one k (ko: k's offset in a row).
#define ACCUMULATE_ROW_K(acc, lrow, ko, b)                                  \
  do {                                                                      \
    _Pragma("unroll") for (int i = 0; i < MR; ++i) {                        \
      const vec_t a = (vec_t)(lrow[i][ko]);                                 \
      _Pragma("unroll") for (int j = 0; j < NV; ++j) acc[i][j] = fma(a, b[j], acc[i][j]); \
    }                                                                       \
  } while (0)

// One element of the result: alpha * acc (+ beta * old). beta == 0 never reads C, so NaN or garbage in
// an output buffer cannot leak into the result (BLAS semantics).
inline float gemm_out(float acc, float alpha, float beta, __global const float* c) {
  return beta == 0.0f ? alpha * acc : fma(alpha, acc, beta * *c);
}

__kernel void gemm_tile(const int P, const int Q, const int K, const float alpha, __global const float* restrict L,
                        const int l_off, const int slp, const int slk, __global const float* restrict R,
                        const int r_off, const int srk, const float beta, __global float* C, const int c_off,
                        const int scp, const int scq) {
  const int p0 = (int)get_global_id(0) * MR;
  if (p0 >= P) return;

  // Rows past P read the last valid row instead (results discarded): the hot loop needs no guard.
  __global const float* lrow[MR];
#pragma unroll
  for (int i = 0; i < MR; ++i) lrow[i] = L + l_off + (size_t)min(p0 + i, P - 1) * slp;
  for (int qt = 0; qt < QT; ++qt) {
    const int q0 = ((int)get_global_id(1) * QT + qt) * NR;
    if (q0 >= Q) return;
    __global const float* r = R + r_off + q0;

    vec_t acc[MR][NV];
#pragma unroll
    for (int i = 0; i < MR; ++i)
#pragma unroll
      for (int j = 0; j < NV; ++j) acc[i][j] = (vec_t)(0.0f);

    if (q0 + NR <= Q) {
      // Full tile along q: vector loads of R.
      for (int k = 0; k < K; ++k) {
        vec_t b[NV];
#pragma unroll
        for (int j = 0; j < NV; ++j) b[j] = VLOAD(0, r + j * VW);
        r += srk;
        ACCUMULATE_ROW_K(acc, lrow, (size_t)k * slk, b);
      }
    } else {
      // Edge tile along q: gather the valid columns one by one (zeros past Q).
      const int qn = Q - q0;
      for (int k = 0; k < K; ++k) {
        vec_t b[NV];
#pragma unroll
        for (int j = 0; j < NV; ++j) {
          vec_u u;
#pragma unroll
          for (int e = 0; e < VW; ++e) u.s[e] = (j * VW + e < qn) ? r[j * VW + e] : 0.0f;
          b[j] = u.v;
        }
        r += srk;
        ACCUMULATE_ROW_K(acc, lrow, (size_t)k * slk, b);
      }
    }

    const bool full_q = q0 + NR <= Q;
#pragma unroll
    for (int i = 0; i < MR; ++i) {
      if (p0 + i >= P) break;
      __global float* c = C + c_off + (size_t)(p0 + i) * scp + (size_t)q0 * scq;
      if (full_q && scq == 1) {
#pragma unroll
        for (int j = 0; j < NV; ++j) {
          vec_t o = alpha * acc[i][j];
          if (beta != 0.0f) o = fma((vec_t)(beta), VLOAD(0, c + j * VW), o);
          VSTORE(o, 0, c + j * VW);
        }
      } else {
#pragma unroll
        for (int j = 0; j < NV; ++j) {
          vec_u u;
          u.v = acc[i][j];
#pragma unroll
          for (int e = 0; e < VW; ++e) {
            const int q = j * VW + e;
            if (q0 + q < Q) {
              __global float* ce = c + (size_t)q * scq;
              *ce = gemm_out(u.s[e], alpha, beta, ce);
            }
          }
        }
      }
    }
  }  // qt
}

// dst[c*ldd + r] = src[r*lds + c] for r < rows, c < cols, with element offsets. Each work-item moves an
// 8x8 block through registers so both the reads and the writes are 8 contiguous floats.
__kernel void transpose_block8(const int rows, const int cols, __global const float* restrict src, const int s_off,
                               const int lds, __global float* restrict dst, const int d_off, const int ldd) {
  const int c0 = (int)get_global_id(0) * 8;
  const int r0 = (int)get_global_id(1) * 8;
  if (r0 >= rows || c0 >= cols) return;
  __global const float* s = src + s_off;
  __global float* d = dst + d_off;
  if (r0 + 8 <= rows && c0 + 8 <= cols) {
    float t[8][8];
#pragma unroll
    for (int i = 0; i < 8; ++i) {
      const float8 v = vload8(0, s + (size_t)(r0 + i) * lds + c0);
      t[i][0] = v.s0; t[i][1] = v.s1; t[i][2] = v.s2; t[i][3] = v.s3;
      t[i][4] = v.s4; t[i][5] = v.s5; t[i][6] = v.s6; t[i][7] = v.s7;
    }
#pragma unroll
    for (int j = 0; j < 8; ++j)
      vstore8((float8)(t[0][j], t[1][j], t[2][j], t[3][j], t[4][j], t[5][j], t[6][j], t[7][j]), 0,
              d + (size_t)(c0 + j) * ldd + r0);
  } else {
    for (int i = r0; i < min(r0 + 8, rows); ++i)
      for (int j = c0; j < min(c0 + 8, cols); ++j) d[(size_t)j * ldd + i] = s[(size_t)i * lds + j];
  }
}
