// Stage-2 feature targets: bilinear reads of the 1/4-resolution relu3_1 maps at full-resolution positions.
// Host side: lib/features/target_gather.cpp; the geometry is documented in lib/features/feature_targets.hpp.
//
// maps: [V][Hf][Wf][C], channels innermost, C a multiple of 8: one work-item walks the C channels of its
// four taps in float8 runs (vectorised inside the work-item, which suits PoCL's CPU device).
// view indices: an I32 tensor on the host (int here).
// TARGETS_F16 (a -D of the host): the maps are stored as IEEE half (host/half.hpp) and read with
// vload_half8, which core OpenCL has without cl_khr_fp16; arithmetic stays in float.

#ifdef TARGETS_F16
typedef half target_t;
#define load_target8(p) vload_half8(0, (p))
#else
typedef float target_t;
#define load_target8(p) vload8(0, (p))
#endif

// The four taps of full-resolution position (px, py) on an hf x wf map: feature coordinate p / 4 - 0.5,
// clamped to [0, n-1] (callers reject non-finite positions first). At the last row/column the second tap repeats the first
// with weight 0, so the sum never reads outside the map.
typedef struct {
  int i0, i1, j0, j1;
  float ly, lx;  // weights of the second row / column
} Taps;

inline Taps target_taps(float px, float py, int hf, int wf) {
  Taps t;
  const float u = fmin(fmax(px * 0.25f - 0.5f, 0.0f), (float)(wf - 1));
  const float v = fmin(fmax(py * 0.25f - 0.5f, 0.0f), (float)(hf - 1));
  t.j0 = (int)u;  // u >= 0: truncation is floor
  t.i0 = (int)v;
  t.j1 = min(t.j0 + 1, wf - 1);
  t.i1 = min(t.i0 + 1, hf - 1);
  t.lx = u - (float)t.j0;
  t.ly = v - (float)t.i0;
  return t;
}

// The four tap rows (C floats each) of view map m at taps t, and their bilinear weights.
typedef struct {
  const global target_t* p[4];  // (i0, j0), (i0, j1), (i1, j0), (i1, j1)
  float w[4];
} TapRows;

inline void tap_rows(const global target_t* m, Taps t, int wf, int C, TapRows* r) {
  r->p[0] = m + ((size_t)t.i0 * wf + t.j0) * C;
  r->p[1] = m + ((size_t)t.i0 * wf + t.j1) * C;
  r->p[2] = m + ((size_t)t.i1 * wf + t.j0) * C;
  r->p[3] = m + ((size_t)t.i1 * wf + t.j1) * C;
  r->w[0] = (1.0f - t.ly) * (1.0f - t.lx);
  r->w[1] = (1.0f - t.ly) * t.lx;
  r->w[2] = t.ly * (1.0f - t.lx);
  r->w[3] = t.ly * t.lx;
}

// Channels [c, c + 8) interpolated.
inline float8 tap_chunk(const TapRows* r, int c) {
  float8 a = r->w[0] * load_target8(r->p[0] + c);
  a = fma((float8)(r->w[1]), load_target8(r->p[1] + c), a);
  a = fma((float8)(r->w[2]), load_target8(r->p[2] + c), a);
  return fma((float8)(r->w[3]), load_target8(r->p[3] + c), a);
}

// out[r][c] = bilinear of maps[view[r]] at pixel_xy[r]. A view index outside [0, V) or a non-finite position
// gives a row of NaN, so a bad input shows up in the loss instead of reading some other pixel.
kernel void targets_gather(global const target_t* maps, global const int* view, global const float* pixel_xy, int R,
                           int V, int hf, int wf, int C, global float* out) {
  const int r = get_global_id(0);
  if (r >= R) return;
  global float* dst = out + (size_t)r * C;
  const int v = view[r];
  const float px = pixel_xy[2 * r], py = pixel_xy[2 * r + 1];
  if (v < 0 || v >= V || !isfinite(px) || !isfinite(py)) {
    for (int c = 0; c < C; c += 8) vstore8((float8)(NAN), 0, dst + c);
    return;
  }
  TapRows rows;
  tap_rows(maps + (size_t)v * hf * wf * C, target_taps(px, py, hf, wf), wf, C, &rows);
  for (int c = 0; c < C; c += 8) vstore8(tap_chunk(&rows, c), 0, dst + c);
}

// OpenCL 1.2 has no float atomics: compare-and-swap on the bits, every access atomic (a plain load of the
// cell before the CAS would race with other work-items' CASes: harmless on hardware, but a data race in
// OpenCL's memory model, which Oclgrind reports).
inline void atomic_add_float(volatile global float* addr, float value) {
  volatile global uint* bits = (volatile global uint*)addr;
  uint seen = 0u;
  for (;;) {
    const uint expect = seen;
    seen = atomic_cmpxchg(bits, expect, as_uint(as_float(expect) + value));
    if (seen == expect) return;
  }
}

inline void scatter_tap(global float* dst, const global float* g, float w, int C) {
  if (w == 0.0f) return;  // the repeated edge tap and exact pixel hits add nothing
  for (int c = 0; c < C; ++c) atomic_add_float(dst + c, w * g[c]);
}

// dmaps += adjoint of targets_gather: each ray adds its gradient row to its four taps. Rays that share a tap
// race, hence the atomic adds (the summation order, and so the last bits, vary between runs). Rays that the
// forward marks NaN (bad view index, non-finite position) contribute nothing. Training never needs this (the
// targets are constants); it is the gather's adjoint, kept for the finite-difference test of the shared
// interpolation.
kernel void targets_gather_backward(global const int* view, global const float* pixel_xy, global const float* dout,
                                    int R, int V, int hf, int wf, int C, global float* dmaps) {
  const int r = get_global_id(0);
  if (r >= R) return;
  const int v = view[r];
  const float px = pixel_xy[2 * r], py = pixel_xy[2 * r + 1];
  if (v < 0 || v >= V || !isfinite(px) || !isfinite(py)) return;
  const Taps t = target_taps(px, py, hf, wf);
  global float* m = dmaps + (size_t)v * hf * wf * C;
  const global float* g = dout + (size_t)r * C;
  scatter_tap(m + ((size_t)t.i0 * wf + t.j0) * C, g, (1.0f - t.ly) * (1.0f - t.lx), C);
  scatter_tap(m + ((size_t)t.i0 * wf + t.j1) * C, g, (1.0f - t.ly) * t.lx, C);
  scatter_tap(m + ((size_t)t.i1 * wf + t.j0) * C, g, t.ly * (1.0f - t.lx), C);
  scatter_tap(m + ((size_t)t.i1 * wf + t.j1) * C, g, t.ly * t.lx, C);
}

// out [1][C][ho][wo] (planar, what the decoder and losses take): output pixel (i, j) is the map of view v at
// full-resolution position (x0 + scale * (j + 0.5), y0 + scale * (i + 0.5)), the centre of its scale x scale
// block. With scale 4 and x0, y0 multiples of 4 every weight is 0 or 1: an exact crop of the map.
kernel void targets_patch(global const target_t* maps, int v, int hf, int wf, int C, int x0, int y0, int scale, int ho,
                          int wo, global float* out) {
  const int p = get_global_id(0);
  if (p >= ho * wo) return;
  const int i = p / wo, j = p - i * wo;
  TapRows rows;
  tap_rows(maps + (size_t)v * hf * wf * C, target_taps(x0 + scale * (j + 0.5f), y0 + scale * (i + 0.5f), hf, wf),
           wf, C, &rows);
  const size_t plane = (size_t)ho * wo;
  global float* dst = out + p;
  for (int c = 0; c < C; c += 8) {
    const float8 a = tap_chunk(&rows, c);
    const float s[8] = {a.s0, a.s1, a.s2, a.s3, a.s4, a.s5, a.s6, a.s7};
    for (int k = 0; k < 8; ++k) dst[(size_t)(c + k) * plane] = s[k];
  }
}
