// Losses: MSE and the AdaIN style loss (mean/std matching). Their final sums use kernels/reduce.cl.
// BLOCK and hsum8 come from kernels/common.cl, which the runtime puts in front of every program.

// Stage 1 of mean((a-b)^2): partials[p] = sum over chunk p of (a-b)^2 (split as in reduce.cl).
__kernel void sqdiff_partials(__global const float* a, __global const float* b, __global float* partials, int n,
                              int chunk) {
  const int p = get_global_id(0);
  const int begin = p * chunk;
  if (begin >= n) return;
  const int end = min(begin + chunk, n);
  __global const float* qa = a + begin;
  __global const float* qb = b + begin;
  const int n8 = (end - begin) / 8;
  float8 total = 0.0f;
  for (int k = 0; k < n8; k += BLOCK) {
    const int e = min(k + BLOCK, n8);
    float8 acc = 0.0f;
    for (int i = k; i < e; ++i) {
      const float8 d = vload8(i, qa) - vload8(i, qb);
      acc = fma(d, d, acc);
    }
    total += acc;
  }
  float s = hsum8(total);
  for (int i = begin + n8 * 8; i < end; ++i) {
    const float d = a[i] - b[i];
    s = fma(d, d, s);
  }
  partials[p] = s;
}

// da = scale * (a - b), scale = 2 * dloss / n. One work-item per SPAN elements (float8, scalar tail).
#define SPAN 64
__kernel void mse_backward(__global const float* a, __global const float* b, __global float* da, int n, float scale) {
  int i = get_global_id(0) * SPAN;
  if (i >= n) return;
  const int end = min(i + SPAN, n);
  for (; i + 8 <= end; i += 8) vstore8(scale * (vload8(0, a + i) - vload8(0, b + i)), 0, da + i);
  for (; i < end; ++i) da[i] = scale * (a[i] - b[i]);
}

// Means come with their rounding residuals lo (kernels/norm.cl): ma - mb between two means near 1e4
// would otherwise carry half an ulp of 1e4 each. (ma - mb) is exact when they are close.
inline float mean_diff(float ma, float la, float mb, float lb) { return (ma - mb) + (la - lb); }

// out[0] = (sum (ma-mb)^2 + sum (sa-sb)^2) / nc over the nc = N*C channel statistics. nc is small
// (hundreds to thousands), so one work-item in a fixed order.
__kernel void style_loss_forward(__global const float* ma, __global const float* la, __global const float* sa,
                                 __global const float* mb, __global const float* lb, __global const float* sb,
                                 __global float* out, int nc) {
  if (get_global_id(0) != 0) return;
  float total = 0.0f;
  for (int k = 0; k < nc; k += BLOCK) {
    const int e = min(k + BLOCK, nc);
    float acc = 0.0f;
    for (int i = k; i < e; ++i) {
      const float dm = mean_diff(ma[i], la[i], mb[i], lb[i]), ds = sa[i] - sb[i];
      acc = fma(dm, dm, fma(ds, ds, acc));
    }
    total += acc;
  }
  out[0] = total / (float)nc;
}

// Gradients of the style loss w.r.t. the statistics of a: dmean = scale (ma - mb), dstd = scale (sa - sb),
// scale = 2 * dloss / nc. channel_stats_backward then carries them to a.
__kernel void style_loss_stat_grads(__global const float* ma, __global const float* la, __global const float* sa,
                                    __global const float* mb, __global const float* lb, __global const float* sb,
                                    __global float* dmean, __global float* dstd, int nc, float scale) {
  const int i = get_global_id(0);
  if (i >= nc) return;
  dmean[i] = scale * mean_diff(ma[i], la[i], mb[i], lb[i]);
  dstd[i] = scale * (sa[i] - sb[i]);
}

// ---- masked losses: the positions of a feature map where a mask is on ------------------------------------
// x [C, HW] (one image), idx [M] positions -> out [C, M]. Global (M, C).
__kernel void gather_positions(__global const float* x, __global const int* idx, __global float* out, int hw, int m) {
  const int i = get_global_id(0), c = get_global_id(1);
  if (i >= m) return;
  out[(long)c * m + i] = x[(long)c * hw + idx[i]];
}

// The transpose: dx[c, idx[i]] = d[c, i]; dx must start at zero (positions are distinct). Global (M, C).
__kernel void scatter_positions(__global const float* d, __global const int* idx, __global float* dx, int hw, int m) {
  const int i = get_global_id(0), c = get_global_id(1);
  if (i >= m) return;
  dx[(long)c * hw + idx[i]] = d[(long)c * m + i];
}
