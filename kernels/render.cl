// Ray marching (box intersection, samples, alpha-mask skip, compaction), compositing forward/backward, and
// dropping low-weight samples. Host side: lib/render/ray_march.cpp, lib/render/composite.cpp.
//
// Integer arrays (ray index, per-ray offset/count, kept indices) are int32 bit patterns stored in float
// tensors; kernels declare them int/uint so the bits are never touched by float arithmetic.

// ---- ray marching -------------------------------------------------------------------------------------
// Seeded per-ray uniform in [0,1) (integer hash, reproduced bit for bit by the tests' CPU reference).
inline float hash_uniform(uint seed, uint i) {
  uint h = i * 0x9E3779B9u ^ seed;
  h ^= h >> 16;
  h *= 0x7feb352du;
  h ^= h >> 15;
  h *= 0x846ca68bu;
  h ^= h >> 16;
  return (float)(h >> 8) * (1.0f / 16777216.0f);
}

typedef struct {
  float3 lo, hi;    // world box
  float near, far;  // t range before clipping to the box
  float step;       // t units between samples
  int max_samples;  // cap on candidate samples per ray (before mask skipping), as TensoRF's N_samples
} MarchParams;

// Slab test: [t_start, t_end] = [max(near, t_enter), min(far, t_exit)]; returns the number of candidate
// samples t_i = t_start + step * (i + jitter) <= t_end (0 for a miss), capped at max_samples.
inline int ray_candidates(const MarchParams* P, float3 o, float3 d, float jitter, float* t_start) {
  float tmin = P->near, tmax = P->far;
  const float oa[3] = {o.x, o.y, o.z}, da[3] = {d.x, d.y, d.z};
  const float lo[3] = {P->lo.x, P->lo.y, P->lo.z}, hi[3] = {P->hi.x, P->hi.y, P->hi.z};
  for (int a = 0; a < 3; ++a) {
    if (da[a] == 0.0f) {
      // Parallel to the slab: inside it for every t or never (no 0 * inf = NaN).
      if (oa[a] < lo[a] || oa[a] > hi[a]) return 0;
    } else {
      const float inv = 1.0f / da[a];
      const float t1 = (lo[a] - oa[a]) * inv, t2 = (hi[a] - oa[a]) * inv;
      tmin = fmax(tmin, fmin(t1, t2));
      tmax = fmin(tmax, fmax(t1, t2));
    }
  }
  *t_start = tmin;
  if (!(tmax >= tmin)) return 0;  // NaN-safe miss
  const float span = (tmax - tmin) / P->step - jitter;
  if (span < 0.0f) return 0;
  return (int)fmin(floor(span) + 1.0f, (float)P->max_samples);
}

// Normalised position of t along the ray, clamped into [-1,1]^3 (a sample inside the t range is inside
// the box; the clamp removes rounding that would push it just outside).
inline float3 normalised_at(const MarchParams* P, float3 o, float3 d, float t) {
  const float3 p = o + t * d;
  return clamp((p - P->lo) / (P->hi - P->lo) * 2.0f - 1.0f, -1.0f, 1.0f);
}

// Mask voxel coordinates along a ray are linear in t: f_a(t) = (o_a + t d_a - lo_a) * m_a / (hi_a - lo_a)
// = a_a + t b_a. Precomputing a and b per ray makes the per-sample test two fmas, a clamp, a truncation and
// one byte load (the normalised position is only computed for samples that are kept). Clamping f to
// [0, m-1] before truncating gives floor for f >= 0 and the border voxel outside, as the clamped
// normalised position would. Count and write passes share this code, so they decide identically.
typedef struct {
  float4 a, b, fmax_;
  int mx, mxy;
} MaskWalk;

inline MaskWalk mask_walk(const MarchParams* P, float3 o, float3 d, int mx, int my, int mz) {
  MaskWalk W;
  const float3 s = (float3)((float)mx, (float)my, (float)mz) / (P->hi - P->lo);
  W.a = (float4)((o - P->lo) * s, 0.0f);
  W.b = (float4)(d * s, 0.0f);
  W.fmax_ = (float4)((float)(mx - 1), (float)(my - 1), (float)(mz - 1), 0.0f);
  W.mx = mx;
  W.mxy = mx * my;
  return W;
}

inline bool occupied_at(global const uchar* mask, const MaskWalk* W, float t) {
  const float4 f = clamp(fma((float4)(t), W->b, W->a), (float4)(0.0f), W->fmax_);
  const int4 v = convert_int4(f);  // truncation: f >= 0
  return mask[v.z * W->mxy + v.y * W->mx + v.x] != 0;
}

#define MARCH_ARGS                                                                                            \
  global const float *origins, global const float *dirs, int R, float lox, float loy, float loz, float hix,   \
      float hiy, float hiz, float near, float far, float step, int max_samples, int jitter_on, uint seed,       \
      global const uchar *mask, int has_mask, int mx, int my, int mz

inline MarchParams march_params(float lox, float loy, float loz, float hix, float hiy, float hiz, float near,
                                float far, float step, int max_samples) {
  MarchParams P;
  P.lo = (float3)(lox, loy, loz);
  P.hi = (float3)(hix, hiy, hiz);
  P.near = near;
  P.far = far;
  P.step = step;
  P.max_samples = max_samples;
  return P;
}

// Pass 1: samples kept per ray.
kernel void march_count(MARCH_ARGS, global int* counts) {
  const int r = get_global_id(0);
  if (r >= R) return;
  const MarchParams P = march_params(lox, loy, loz, hix, hiy, hiz, near, far, step, max_samples);
  const float3 o = vload3(r, origins), d = vload3(r, dirs);
  const float jitter = jitter_on ? hash_uniform(seed, (uint)r) : 0.0f;
  float t0;
  const int n = ray_candidates(&P, o, d, jitter, &t0);
  if (!has_mask) {
    counts[r] = n;
    return;
  }
  const MaskWalk W = mask_walk(&P, o, d, mx, my, mz);
  int c = 0;
  for (int i = 0; i < n; ++i) c += occupied_at(mask, &W, t0 + P.step * ((float)i + jitter)) ? 1 : 0;
  counts[r] = c;
}

// Pass 2 (after the host's exclusive prefix sum of counts into offsets): the same walk, writing samples.
kernel void march_write(MARCH_ARGS, global const int* offsets, global float* pos, global float* tvals,
                        global float* deltas, global int* ray_index, float delta_scale) {
  const int r = get_global_id(0);
  if (r >= R) return;
  const MarchParams P = march_params(lox, loy, loz, hix, hiy, hiz, near, far, step, max_samples);
  const float3 o = vload3(r, origins), d = vload3(r, dirs);
  const float jitter = jitter_on ? hash_uniform(seed, (uint)r) : 0.0f;
  const float delta = P.step * length(d) * delta_scale;
  float t0;
  const int n = ray_candidates(&P, o, d, jitter, &t0);
  int k = offsets[r];
  const MaskWalk W = mask_walk(&P, o, d, mx, my, mz);
  for (int i = 0; i < n; ++i) {
    const float t = t0 + P.step * ((float)i + jitter);
    if (has_mask && !occupied_at(mask, &W, t)) continue;
    const float3 q = normalised_at(&P, o, d, t);
    vstore3(q, k, pos);
    tvals[k] = t;
    deltas[k] = delta;
    ray_index[k] = r;
    ++k;
  }
}

// ---- compositing ---------------------------------------------------------------------------------------
// Optical depth of one sample: sigma * delta, 0 when delta <= 0 (no inf * 0) and never negative (negative
// or NaN sigma counts as empty; fmax returns the non-NaN operand).
inline float optical_depth(float sigma, float delta) { return delta > 0.0f ? fmax(sigma * delta, 0.0f) : 0.0f; }
// alpha = 1 - exp(-x) from e = exp(-x) (one exp per sample): for small x, 1 - e loses digits, so use the
// series x (1 - x/2 (1 - x/3)) there (relative error < x^3/24 < 5e-8 at x < 1e-2).
inline float alpha_of(float x, float e) { return x < 1e-2f ? x * (1.0f - 0.5f * x * (1.0f - x * (1.0f / 3.0f))) : 1.0f - e; }
inline float dx_dsigma(float sigma, float delta) { return (delta > 0.0f && sigma >= 0.0f) ? delta : 0.0f; }

// Per ray r over its samples [off, off+cnt): alpha_i = 1 - exp(-x_i), w_i = T_i alpha_i with
// T_i = prod_{j<i} exp(-x_j) (a product of values in [0,1]: underflows to 0, never to NaN),
// acc = sum w, depth = sum w_i t_i (no background depth), val = sum w_i c_i + (1 - acc) bg (bg if has_bg).
kernel void composite_forward(global const float* sigma, global const float* vals, global const float* deltas,
                              global const float* tvals, global const int* offsets, global const int* counts, int R,
                              int C, global const float* bg, int has_bg, global float* out_val, global float* out_acc,
                              global float* out_depth, global float* weights) {
  const int r = get_global_id(0);
  if (r >= R) return;
  const int off = offsets[r], cnt = counts[r];
  global float* ov = out_val + (long)r * C;
  for (int c = 0; c < C; ++c) ov[c] = 0.0f;
  float T = 1.0f, acc = 0.0f, depth = 0.0f;
  for (int k = off; k < off + cnt; ++k) {
    const float x = optical_depth(sigma[k], deltas[k]);
    const float e = exp(-x);
    const float w = T * alpha_of(x, e);
    T *= e;
    acc += w;
    depth = fma(w, tvals[k], depth);
    const global float* cv = vals + (long)k * C;
    for (int c = 0; c < C; ++c) ov[c] = fma(w, cv[c], ov[c]);
    weights[k] = w;
  }
  if (has_bg)
    for (int c = 0; c < C; ++c) ov[c] = fma(1.0f - acc, bg[c], ov[c]);
  out_acc[r] = acc;
  out_depth[r] = depth;
}

// Backward: with v_i = dL/dw_i = <dval, c_i - bg> + dacc + ddepth t_i (bg term only with has_bg),
// dL/dx_k = v_k T_{k+1} - sum_{i>k} v_i w_i (w_i = T_i - T_{i+1}); dsigma_k = dL/dx_k * dx_k/dsigma_k and
// dc_k = w_k dval. Two forward passes: the first totals sum_i v_i w_i, the second subtracts the running
// prefix, so no per-ray storage is needed.
inline float sample_v(const global float* vals, int k, int C, const global float* dv, const global float* bg,
                      int has_bg, float dacc, float ddepth, float t) {
  float v = dacc + ddepth * t;
  const global float* cv = vals + (long)k * C;
  if (dv)
    for (int c = 0; c < C; ++c) v = fma(dv[c], cv[c] - (has_bg ? bg[c] : 0.0f), v);
  return v;
}

kernel void composite_backward(global const float* sigma, global const float* vals, global const float* deltas,
                               global const float* tvals, global const int* offsets, global const int* counts, int R,
                               int C, global const float* bg, int has_bg, global const float* dval, int has_dval,
                               global const float* dacc, int has_dacc, global const float* ddepth, int has_ddepth,
                               global float* dsigma, global float* dvals) {
  const int r = get_global_id(0);
  if (r >= R) return;
  const int off = offsets[r], cnt = counts[r];
  const global float* dv = has_dval ? dval + (long)r * C : 0;
  const float da = has_dacc ? dacc[r] : 0.0f, dd = has_ddepth ? ddepth[r] : 0.0f;
  float T = 1.0f, total = 0.0f;
  for (int k = off; k < off + cnt; ++k) {
    const float x = optical_depth(sigma[k], deltas[k]);
    const float e = exp(-x);
    const float w = T * alpha_of(x, e);
    T *= e;
    total = fma(sample_v(vals, k, C, dv, bg, has_bg, da, dd, tvals[k]), w, total);
    global float* dc = dvals + (long)k * C;
    for (int c = 0; c < C; ++c) dc[c] = dv ? w * dv[c] : 0.0f;
  }
  T = 1.0f;
  float prefix = 0.0f;
  for (int k = off; k < off + cnt; ++k) {
    const float s = sigma[k], dl = deltas[k];
    const float x = optical_depth(s, dl);
    const float e = exp(-x);
    const float w = T * alpha_of(x, e);
    const float Tn = T * e;
    const float v = sample_v(vals, k, C, dv, bg, has_bg, da, dd, tvals[k]);
    prefix = fma(v, w, prefix);
    const float dx = v * Tn - (total - prefix);
    dsigma[k] = dx * dx_dsigma(s, dl);
    T = Tn;
  }
}

// ---- dropping low-weight samples -------------------------------------------------------------------------
// Pass 1: per ray, how many samples have w >= thr.
kernel void keep_count(global const float* weights, global const int* offsets, global const int* counts, int R,
                       float thr, global int* kept) {
  const int r = get_global_id(0);
  if (r >= R) return;
  int c = 0;
  for (int k = offsets[r]; k < offsets[r] + counts[r]; ++k) c += weights[k] >= thr;
  kept[r] = c;
}

// Pass 2: indices (into the original sample list) of the kept samples, at the scanned offsets.
kernel void keep_write(global const float* weights, global const int* offsets, global const int* counts, int R,
                       float thr, global const int* kept_offsets, global int* kept_index) {
  const int r = get_global_id(0);
  if (r >= R) return;
  int j = kept_offsets[r];
  for (int k = offsets[r]; k < offsets[r] + counts[r]; ++k)
    if (weights[k] >= thr) kept_index[j++] = k;
}

// dst[i, :] = src[idx[i], :] over C 32-bit words (bits copied as uint: works for float and int payloads).
kernel void gather_rows(global const uint* src, global const int* idx, global uint* dst, int n, int C) {
  const int i = get_global_id(0);
  if (i >= n) return;
  const global uint* s = src + (long)idx[i] * C;
  global uint* d = dst + (long)i * C;
  for (int c = 0; c < C; ++c) d[c] = s[c];
}

// dst[idx[i], :] = src[i, :] (dst zeroed by the host; indices distinct).
kernel void scatter_rows(global const uint* src, global const int* idx, global uint* dst, int n, int C) {
  const int i = get_global_id(0);
  if (i >= n) return;
  const global uint* s = src + (long)i * C;
  global uint* d = dst + (long)idx[i] * C;
  for (int c = 0; c < C; ++c) d[c] = s[c];
}
