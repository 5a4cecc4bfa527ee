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
  const int j = get_global_id(0) * 8, n = get_global_id(1);
  if (j >= cols || n >= rows) return;
  const int width = min(8, cols - j);
  const long o = (long)n * cols + j;
  for (int k = 0; k < width; ++k) y[o + k] = (x[o + k] - mean[j + k]) * rsqrt(var[j + k] + eps);
}

// Backward through batch statistics (training mode): with s = rsqrt(var + eps) and K rows,
//   dx = s * (dy - mean_n(dy) - y * mean_n(dy * y))
// sum_dy and sum_dyy are column sums of dy and dy * y. fixed != 0: statistics are constants (evaluation,
// running statistics): dx = s * dy.
__kernel void point_norm_backward(__global const float* y, __global const float* var, __global const float* dy,
                                  __global const float* sum_dy, __global const float* sum_dyy, __global float* dx,
                                  int rows, int cols, float eps, int fixed) {
  const int j = get_global_id(0) * 8, n = get_global_id(1);
  if (j >= cols || n >= rows) return;
  const int width = min(8, cols - j);
  const long o = (long)n * cols + j;
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
#define E 32

// The softmax row i of a point: p_ij = exp(q_i k_j - m_i) / Z_i. The largest logit of row i is q_i times
// the largest (q_i >= 0) or the smallest (q_i < 0) k_j, so m_i costs nothing and exp never overflows
// (logits of +-1e5 saturate to a one-hot row, as they should).
inline float row_max(float qi, float kmax, float kmin) { return qi >= 0.0f ? qi * kmax : qi * kmin; }

// Global: rows. qkv [K, 3E] (q | k | v), out [K, E].
__kernel void channel_attention_forward(__global const float* qkv, __global float* out, int rows) {
  const int n = get_global_id(0);
  if (n >= rows) return;
  __global const float* r = qkv + (long)n * 3 * E;
  float k[E], v[E];
  float kmax = -INFINITY, kmin = INFINITY;
  for (int j = 0; j < E; ++j) {
    k[j] = r[E + j];
    v[j] = r[2 * E + j];
    kmax = fmax(kmax, k[j]);
    kmin = fmin(kmin, k[j]);
  }
  for (int i = 0; i < E; ++i) {
    const float qi = r[i];
    const float m = row_max(qi, kmax, kmin);
    float z = 0.0f, acc = 0.0f;
    for (int j = 0; j < E; ++j) {
      const float e = exp(fma(qi, k[j], -m));
      z += e;
      acc = fma(e, v[j], acc);
    }
    out[(long)n * E + i] = acc / z;
  }
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
  float k[E], v[E], dk[E], dv[E];
  float kmax = -INFINITY, kmin = INFINITY;
  for (int j = 0; j < E; ++j) {
    k[j] = r[E + j];
    v[j] = r[2 * E + j];
    kmax = fmax(kmax, k[j]);
    kmin = fmin(kmin, k[j]);
    dk[j] = 0.0f;
    dv[j] = 0.0f;
  }
  __global float* d = dqkv + (long)n * 3 * E;
  for (int i = 0; i < E; ++i) {
    const float qi = r[i], gi = g[i];
    const float m = row_max(qi, kmax, kmin);
    float p[E];
    float z = 0.0f, o = 0.0f;
    for (int j = 0; j < E; ++j) {
      p[j] = exp(fma(qi, k[j], -m));
      z += p[j];
      o = fma(p[j], v[j], o);
    }
    const float inv_z = 1.0f / z;
    o *= inv_z;
    float dq = 0.0f;
    for (int j = 0; j < E; ++j) {
      const float pij = p[j] * inv_z;
      const float pg = pij * gi;
      dv[j] += pg;
      const float ds = pg * (v[j] - o);
      dq = fma(ds, k[j], dq);
      dk[j] = fma(ds, qi, dk[j]);
    }
    d[i] = dq;
  }
  for (int j = 0; j < E; ++j) {
    d[E + j] = dk[j];
    d[2 * E + j] = dv[j];
  }
}
