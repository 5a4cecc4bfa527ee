// Sampling-invariant content transformation (StyleRF Sec. 3.2), per sampled 3D point, rows layout:
// x [K, C] (one row per kept sample), lib/style/sict.cpp. Three pieces:
//   1. (column statistics over the points: kernels/columns.cl, lib/nn/columns.hpp)
//   2. the normalisation y = (x - mean) * rsqrt(var + eps) and its backward (batch or fixed statistics);
//   3. channel self-attention per point: out_i = sum_j softmax_j(q_i k_j) v_j over the E = 32 channels
//      of that point's q, k, v (the rows of qkv [K, 3E]), and its backward.

// ---- 2. normalisation -------------------------------------------------------------------------------
// Global (ceil(cols/8), rows). y = (x - mean) * rsqrt(var + eps).
__kernel void point_norm_forward(__global const float* x, __global const float* mean, __global const float* var,
                                 __global float* y, int rows, int cols, float eps) {
  COLUMN_BLOCK_OR_RETURN(rows, cols)
  for (int k = 0; k < width; ++k) y[o + k] = (x[o + k] - mean[j + k]) * rsqrt(var[j + k] + eps);
}

// Backward through batch statistics (training mode): with s = rsqrt(var + eps) and K rows,
//   dx = s * (dy - mean_n(dy) - y * mean_n(dy * y))
// sum_dy and sum_dyy are column sums of dy and dy * y. fixed != 0: statistics are constants (evaluation,
// running statistics): dx = s * dy.
__kernel void point_norm_backward(__global const float* y, __global const float* var, __global const float* dy,
                                  __global const float* sum_dy, __global const float* sum_dyy, __global float* dx,
                                  int rows, int cols, float eps, int fixed) {
  COLUMN_BLOCK_OR_RETURN(rows, cols)
  const float inv_k = 1.0f / (float)rows;
  for (int k = 0; k < width; ++k) {
    const float s = rsqrt(var[j + k] + eps);
    if (fixed) {
      dx[o + k] = s * dy[o + k];
    } else {
      dx[o + k] = s * (dy[o + k] - sum_dy[j + k] * inv_k - y[o + k] * sum_dyy[j + k] * inv_k);
    }
  }
}

// Running statistics (PyTorch's InstanceNorm1d with track_running_stats): a momentum step towards the
// batch mean and the UNBIASED batch variance (var * K / (K - 1)). One point has no unbiased variance:
// then only the mean moves. Global: cols.
__kernel void running_stats_update(__global float* running_mean, __global float* running_var,
                                   __global const float* mean, __global const float* var, int cols, int rows,
                                   float momentum) {
  const int j = get_global_id(0);
  if (j >= cols) return;
  running_mean[j] = (1.0f - momentum) * running_mean[j] + momentum * mean[j];
  if (rows > 1) {
    const float unbiased = var[j] * (float)rows / (float)(rows - 1);
    running_var[j] = (1.0f - momentum) * running_var[j] + momentum * unbiased;
  }
}

// ---- 3. channel self-attention ----------------------------------------------------------------------
// E, the embedding width, is the host's Sict::kEmbed, passed as -DSICT_EMBED (lib/style/sict.cpp,
// sict_build_options): a build without it, or with a width the float16 loads below do not fit, fails.
#ifndef SICT_EMBED
#error "build sict.cl with -DSICT_EMBED=<style::Sict::kEmbed> (lib/style/sict.cpp: sict_build_options)"
#endif
#if SICT_EMBED != 32
#error "sict.cl's channel attention holds a row's keys and values in two float16 registers: SICT_EMBED must be 32"
#endif
#define E SICT_EMBED

// The softmax row i of a point: p_ij = exp(q_i k_j - m_i) / Z_i. The largest logit of row i is q_i times
// the largest (q_i >= 0) or the smallest (q_i < 0) k_j, so m_i costs nothing and exp never overflows
// (logits of +-1e5 saturate to a one-hot row, as they should).
inline float row_max(float qi, float kmax, float kmin) { return qi >= 0.0f ? qi * kmax : qi * kmin; }

// Horizontal reductions of 16 lanes.
inline float hsum16(float16 v) {
  const float8 a = v.lo + v.hi;
  const float4 b = a.lo + a.hi;
  return b.x + b.y + b.z + b.w;
}
inline float hmax16(float16 v) {
  const float8 a = fmax(v.lo, v.hi);
  const float4 b = fmax(a.lo, a.hi);
  return fmax(fmax(b.x, b.y), fmax(b.z, b.w));
}
inline float hmin16(float16 v) {
  const float8 a = fmin(v.lo, v.hi);
  const float4 b = fmin(a.lo, a.hi);
  return fmin(fmin(b.x, b.y), fmin(b.z, b.w));
}

// Row maxima of all 32 softmax rows of a point at once (lanes are rows i): row_max, lane by lane.
inline float16 row_max16(float16 q, float kmax, float kmin) { return select(q * kmin, q * kmax, q >= 0.0f); }

// Global: rows. qkv [K, 3E] (q | k | v), out [K, E]. The lanes of two float16 are the point's 32 softmax
// rows i, and the loop runs over the channels j: each step is one exp and two multiply-adds on 16 lanes,
// with no horizontal sum (a loop over rows with the lanes on j spent as much time in its 64 horizontal
// sums and 32 scalar divides as in the exponentials).
__kernel void channel_attention_forward(__global const float* qkv, __global float* out, int rows) {
  const int n = get_global_id(0);
  if (n >= rows) return;
  __global const float* r = qkv + (long)n * 3 * E;
  const float16 q0 = vload16(0, r), q1 = vload16(1, r);
  const float16 k0 = vload16(0, r + E), k1 = vload16(1, r + E);
  const float kmax = hmax16(fmax(k0, k1)), kmin = hmin16(fmin(k0, k1));
  const float16 m0 = row_max16(q0, kmax, kmin), m1 = row_max16(q1, kmax, kmin);
  float16 z0 = 0.0f, z1 = 0.0f, a0 = 0.0f, a1 = 0.0f;
  for (int j = 0; j < E; ++j) {
    const float kj = r[E + j], vj = r[2 * E + j];
    const float16 e0 = exp(fma(q0, (float16)kj, -m0)), e1 = exp(fma(q1, (float16)kj, -m1));
    z0 += e0;
    z1 += e1;
    a0 = fma(e0, (float16)vj, a0);
    a1 = fma(e1, (float16)vj, a1);
  }
  vstore16(a0 / z0, 0, out + (long)n * E);
  vstore16(a1 / z1, 1, out + (long)n * E);
}

// With g_i = dout_i and o_i = out_i:
//   dv_j = sum_i p_ij g_i;   ds_ij = p_ij g_i (v_j - o_i);   dq_i = sum_j ds_ij k_j;   dk_j = sum_i ds_ij q_i.
// Recomputes p from q and k (96 floats a point kept instead of 1024). Global: rows. dqkv [K, 3E].
__kernel void channel_attention_backward(__global const float* qkv, __global const float* dout,
                                         __global float* dqkv, int rows) {
  const int n = get_global_id(0);
  if (n >= rows) return;
  __global const float* r = qkv + (long)n * 3 * E;
  __global const float* g = dout + (long)n * E;
  const float16 k0 = vload16(0, r + E), k1 = vload16(1, r + E);
  const float16 v0 = vload16(0, r + 2 * E), v1 = vload16(1, r + 2 * E);
  const float kmax = hmax16(fmax(k0, k1)), kmin = hmin16(fmin(k0, k1));
  float16 dk0 = 0.0f, dk1 = 0.0f, dv0 = 0.0f, dv1 = 0.0f;
  __global float* d = dqkv + (long)n * 3 * E;
  for (int i = 0; i < E; ++i) {
    const float qi = r[i], gi = g[i];
    const float m = row_max(qi, kmax, kmin);
    const float16 p0 = exp(fma((float16)qi, k0, (float16)(-m))), p1 = exp(fma((float16)qi, k1, (float16)(-m)));
    const float inv_z = 1.0f / hsum16(p0 + p1);
    const float o = hsum16(p0 * v0 + p1 * v1) * inv_z;
    const float16 pg0 = p0 * (inv_z * gi), pg1 = p1 * (inv_z * gi);
    dv0 += pg0;
    dv1 += pg1;
    const float16 ds0 = pg0 * (v0 - o), ds1 = pg1 * (v1 - o);
    dk0 = fma(ds0, (float16)qi, dk0);
    dk1 = fma(ds1, (float16)qi, dk1);
    d[i] = hsum16(ds0 * k0 + ds1 * k1);
  }
  vstore16(dk0, 0, d + E);
  vstore16(dk1, 1, d + E);
  vstore16(dv0, 0, d + 2 * E);
  vstore16(dv1, 1, d + 2 * E);
}

// ---- 3b. channel attention on work-groups (GPUs) --------------------------------------------------------------
// The same op for devices where one work-item per point is slow: its 32 keys, 32 values and their gradients
// held in registers (200+ a work-item) leave a GPU few warps, and each work-item's 384-byte row makes
// uncoalesced loads. Here a work-group of AG_ROWS points x E lanes loads its rows into __local memory with
// neighbouring lanes reading neighbouring floats, and lane i of a point computes that point's output i,
// reading the keys and values from __local memory (every lane of a point reads the same word: a broadcast).
// The row maximum m_i is the same exact maximum as row_max's. lib/style/sict.cpp chooses the path with the
// reductions' (nn::ReductionPath: STYLERF_REDUCTION, work-groups on GPUs).
#define AG_ROWS (256 / E)
#define AG_LANES (AG_ROWS * E)

// Loads `count` floats from src into dst with the whole group (coalesced).
inline void group_load(__local float* dst, __global const float* src, int count) {
  for (int o = get_local_id(0); o < count; o += AG_LANES) dst[o] = src[o];
}

inline float row_max_local(float qi, __local const float* k) {
  float kmax = k[0], kmin = k[0];
  for (int j = 1; j < E; ++j) {
    kmax = fmax(kmax, k[j]);
    kmin = fmin(kmin, k[j]);
  }
  return row_max(qi, kmax, kmin);
}

// Z_i = sum_j e_ij and sum_j e_ij v_j, with e_ij = exp(q_i k_j - m) over a point's E channels (__local rows):
// the softmax's normaliser and numerator of out_i (forward, and the backward's first pass).
inline float2 softmax_sums_local(float qi, __local const float* k, __local const float* v, float m) {
  float z = 0.0f, acc = 0.0f;
  for (int j = 0; j < E; ++j) {
    const float e = exp(fma(qi, k[j], -m));
    z += e;
    acc = fma(e, v[j], acc);
  }
  return (float2)(z, acc);
}

// Global: ceil(rows / AG_ROWS) * AG_LANES, local AG_LANES.
__kernel __attribute__((reqd_work_group_size(AG_LANES, 1, 1)))
void channel_attention_forward_group(__global const float* qkv, __global float* out, int rows) {
  __local float t[AG_ROWS * 3 * E];
  const long base = (long)get_group_id(0) * AG_ROWS;
  const int nrows = min((long)AG_ROWS, rows - base);
  group_load(t, qkv + base * 3 * E, nrows * 3 * E);
  barrier(CLK_LOCAL_MEM_FENCE);
  const int r = get_local_id(0) / E, i = get_local_id(0) % E;
  if (r >= nrows) return;
  __local const float* q = t + r * 3 * E;
  __local const float *k = q + E, *v = q + 2 * E;
  const float qi = q[i];
  const float2 sums = softmax_sums_local(qi, k, v, row_max_local(qi, k));
  out[(base + r) * E + i] = sums.y / sums.x;
}

// Two phases: lane i of a point computes Z_i, o_i and dq_i = sum_j ds_ij k_j, and leaves m_i, a_i = g_i / Z_i
// and o_i in __local memory; then lane j sums over i: dv_j = sum_i p_ij g_i = sum_i e_ij a_i and
// dk_j = sum_i ds_ij q_i with ds_ij = e_ij a_i (v_j - o_i). The exps are recomputed in each pass instead
// of keeping a 32 x 32 matrix a point (exp is cheap on a GPU; registers are not).
__kernel __attribute__((reqd_work_group_size(AG_LANES, 1, 1)))
void channel_attention_backward_group(__global const float* qkv, __global const float* dout,
                                      __global float* dqkv, int rows) {
  __local float t[AG_ROWS * 3 * E], g[AG_ROWS * E], ml[AG_ROWS * E], al[AG_ROWS * E], ol[AG_ROWS * E];
  const long base = (long)get_group_id(0) * AG_ROWS;
  const int nrows = min((long)AG_ROWS, rows - base);
  group_load(t, qkv + base * 3 * E, nrows * 3 * E);
  group_load(g, dout + base * E, nrows * E);
  barrier(CLK_LOCAL_MEM_FENCE);
  const int lane = get_local_id(0), r = lane / E, i = lane % E;
  const bool active = r < nrows;
  __local const float* q = t + r * 3 * E;
  __local const float *k = q + E, *v = q + 2 * E;
  __global float* d = dqkv + (base + r) * 3 * E;
  if (active) {
    const float qi = q[i], m = row_max_local(qi, k);
    const float2 sums = softmax_sums_local(qi, k, v, m);
    const float z = sums.x, o = sums.y / z, a = g[lane] / z;
    float dq = 0.0f;
    for (int j = 0; j < E; ++j) dq = fma(exp(fma(qi, k[j], -m)) * a * (v[j] - o), k[j], dq);
    d[i] = dq;
    ml[lane] = m;
    al[lane] = a;
    ol[lane] = o;
  }
  barrier(CLK_LOCAL_MEM_FENCE);
  if (!active) return;
  const int j = i;
  const float kj = k[j], vj = v[j];
  float dk = 0.0f, dv = 0.0f;
  for (int ii = 0; ii < E; ++ii) {
    const int s = r * E + ii;
    const float pa = exp(fma(q[ii], kj, -ml[s])) * al[s];
    dv += pa;
    dk = fma(pa * (vj - ol[s]), q[ii], dk);
  }
  d[E + j] = dk;
  d[2 * E + j] = dv;
}
