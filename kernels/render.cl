// Ray marching (box intersection, samples, alpha-mask skip, compaction) and dropping low-weight samples
// (compositing: kernels/composite.cl). Host side: lib/render/ray_march.cpp, lib/render/composite.cpp.
//
// Integer arrays (ray index, per-ray offset/count, kept indices) are I32 tensors (int here); the alpha mask
// is a U8 tensor (uchar). gather_rows/scatter_rows copy 32-bit words (uint), so they move F32 and I32 rows
// alike, bit for bit.

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
      uint ray_base, global const uchar *mask, int has_mask, int mx, int my, int mz

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
  const float jitter = jitter_on ? hash_uniform(seed, ray_base + (uint)r) : 0.0f;
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

// Pass 2 (after the host's exclusive prefix sum of counts into offsets): the same walk, writing samples,
// and stopping after counts[r] of them (fewer than the walk has when a ray was terminated early:
// kernels/march_density.cl).
kernel void march_write(MARCH_ARGS, global const int* offsets, global const int* counts, global float* pos,
                        global float* tvals, global float* deltas, global int* ray_index, float delta_scale) {
  const int r = get_global_id(0);
  if (r >= R) return;
  const MarchParams P = march_params(lox, loy, loz, hix, hiy, hiz, near, far, step, max_samples);
  const float3 o = vload3(r, origins), d = vload3(r, dirs);
  const float jitter = jitter_on ? hash_uniform(seed, ray_base + (uint)r) : 0.0f;
  const float delta = P.step * length(d) * delta_scale;
  float t0;
  const int n = ray_candidates(&P, o, d, jitter, &t0);
  int k = offsets[r];
  const int end = k + counts[r];
  const MaskWalk W = mask_walk(&P, o, d, mx, my, mz);
  for (int i = 0; i < n && k < end; ++i) {
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
