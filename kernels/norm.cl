// Per-channel statistics, instance norm and AdaIN, forward and backward.
//
// A tensor [N,C,H,W] is seen as nc = N*C channels of hw = H*W contiguous floats.
// Reductions: one work-item owns a whole channel (on a CPU device a work-item is one iteration of the
// work-group loop; float8 vectors give the SIMD), so there are no barriers and the order of additions
// is fixed: results are deterministic. Channels longer than a chunk (lib/nn/norm.cpp) are summed in
// chunks by several work-items, then the chunk sums in order (the "chunked" kernels below). Elementwise
// passes: one work-item per SPAN floats of a channel (float8 loop, scalar tail), global size
// (ceil(hw / SPAN), nc); 64 floats per work-item measured ~1.5x
// faster than 8 on PoCL (less per-work-item overhead).
//
// Precision: sums are blocked (a fresh float8 accumulator every BLOCK vectors) so rounding error grows
// with BLOCK + hw / (8 * BLOCK) terms rather than hw. Variance uses the corrected two-pass algorithm:
// pass 1 gives an approximate mean m0; pass 2 sums d = x - m0 and d^2, and
//   mean = m0 + sum(d) / hw,   var = (sum(d^2) - sum(d)^2 / hw) / hw,
// which removes the error of m0 to first order. A float mean of data like 1e4 +- 1e-2 is only good to
// half an ulp of 1e4 (~5e-4, i.e. 5% of the std), so the stats kernel also returns the rounding
// residual mean_lo (true mean ~ mean + mean_lo) and the normalising kernels subtract both:
// (x - mean) is exact for x near mean, and then - mean_lo restores the lost digits.
// BLOCK, hsum8 and blocked_sum (pass 1) come from kernels/common.cl, which the runtime puts in front of every program.

#define SPAN 64

// Pass 2 over p[0, n): *sd = sum(d), *sq = sum(d^2) with d = x - m0, blocked as above.
inline void centred_sums(__global const float* p, int n, float m0, float* sd_out, float* sq_out) {
  const int n8 = n / 8;
  float8 tot_d = 0.0f, tot_q = 0.0f;
  for (int b = 0; b < n8; b += BLOCK) {
    const int e = min(b + BLOCK, n8);
    float8 acc_d = 0.0f, acc_q = 0.0f;
    for (int i = b; i < e; ++i) {
      const float8 d = vload8(i, p) - m0;
      acc_d += d;
      acc_q = fma(d, d, acc_q);
    }
    tot_d += acc_d;
    tot_q += acc_q;
  }
  float sd = hsum8(tot_d), sq = hsum8(tot_q);
  for (int i = n8 * 8; i < n; ++i) {
    const float d = p[i] - m0;
    sd += d;
    sq = fma(d, d, sq);
  }
  *sd_out = sd;
  *sq_out = sq;
}

// mean, mean_lo and std of channel c from m0 and the centred sums.
inline void write_stats(int c, float m0, float sd, float sq, int hw, float eps, __global float* mean,
                        __global float* stdv, __global float* mean_lo) {
  const float corr = sd / (float)hw;
  const float var = max((sq - sd * corr) / (float)hw, 0.0f);
  // TwoSum: m = fl(m0 + corr) and the exact rounding error lo, so m + lo == m0 + corr.
  const float m = m0 + corr;
  const float bb = m - m0;
  mean[c] = m;
  mean_lo[c] = (m0 - (m - bb)) + (corr - bb);
  stdv[c] = sqrt(var + eps);
}

// mean, std = sqrt(var + eps) and mean_lo (see above) for each channel.
__kernel void channel_stats_forward(__global const float* x, __global float* mean, __global float* stdv,
                                    __global float* mean_lo, int hw, float eps, int nc) {
  const int c = get_global_id(0);
  if (c >= nc) return;
  __global const float* p = x + c * hw;
  const float m0 = blocked_sum(p, hw) / (float)hw;
  float sd, sq;
  centred_sums(p, hw, m0, &sd, &sq);
  write_stats(c, m0, sd, sq, hw, eps, mean, stdv, mean_lo);
}

// ---- the same statistics over long channels, several work-items a channel --------------------------
// One work-item per channel left a GPU nearly idle (channel_stats_forward took 62% of an H100's decoder
// step). For hw above a chunk the host (lib/nn/norm.cpp) cuts each channel into `chunks` chunks of
// `chunk` floats and the sums above are taken per chunk, then added in chunk order: still deterministic.
// Global (chunks, nc) for the partial kernels, (nc) for the finishing ones.

// The approximate mean m0 of channel c from its chunk sums, added in order.
inline float chunked_mean(__global const float* psum, int c, int chunks, int hw) {
  float s = 0.0f;
  for (int k = 0; k < chunks; ++k) s += psum[c * chunks + k];
  return s / (float)hw;
}

__kernel void channel_sums_chunked(__global const float* x, __global float* psum, int hw, int chunk, int chunks) {
  const int k = get_global_id(0), c = get_global_id(1);
  if (k >= chunks) return;
  const int j0 = k * chunk;
  psum[c * chunks + k] = blocked_sum(x + (long)c * hw + j0, max(0, min(chunk, hw - j0)));
}

// Pass 2 per chunk: sums of d = x - m0 and d^2.
__kernel void channel_centred_sums_chunked(__global const float* x, __global const float* psum, __global float* pd,
                                           __global float* pq, int hw, int chunk, int chunks) {
  const int k = get_global_id(0), c = get_global_id(1);
  if (k >= chunks) return;
  const int j0 = k * chunk;
  float sd, sq;
  centred_sums(x + (long)c * hw + j0, max(0, min(chunk, hw - j0)), chunked_mean(psum, c, chunks, hw), &sd, &sq);
  pd[c * chunks + k] = sd;
  pq[c * chunks + k] = sq;
}

// write_stats of channel c from m0 and its chunk sums of d and d^2, added in chunk order (also the
// work-group path's finish: kernels/group_reduce.cl).
inline void write_stats_from_chunks(int c, float m0, __global const float* pd, __global const float* pq, int chunks,
                                    int hw, float eps, __global float* mean, __global float* stdv,
                                    __global float* mean_lo) {
  float sd = 0.0f, sq = 0.0f;
  for (int k = 0; k < chunks; ++k) {
    sd += pd[c * chunks + k];
    sq += pq[c * chunks + k];
  }
  write_stats(c, m0, sd, sq, hw, eps, mean, stdv, mean_lo);
}

// mean, mean_lo and std from the chunk sums.
__kernel void channel_stats_finish(__global const float* psum, __global const float* pd, __global const float* pq,
                                   __global float* mean, __global float* stdv, __global float* mean_lo, int hw,
                                   int chunks, float eps, int nc) {
  const int c = get_global_id(0);
  if (c >= nc) return;
  write_stats_from_chunks(c, chunked_mean(psum, c, chunks, hw), pd, pq, chunks, hw, eps, mean, stdv, mean_lo);
}

// y = ((x - mean) - mean_lo) / std
__kernel void instance_norm_forward(__global const float* x, __global const float* mean,
                                    __global const float* stdv, __global const float* mean_lo,
                                    __global float* y, int hw) {
  const int j0 = get_global_id(0) * SPAN;
  const int c = get_global_id(1);
  if (j0 >= hw) return;
  const int end = c * hw + min(j0 + SPAN, hw);
  const float m = mean[c], lo = mean_lo[c], inv = 1.0f / stdv[c];
  int o = c * hw + j0;
  for (; o + 8 <= end; o += 8) vstore8(((vload8(0, x + o) - m) - lo) * inv, 0, y + o);
  for (; o < end; ++o) y[o] = ((x[o] - m) - lo) * inv;
}

// AdaIN: y = ((x - mean_c) - lo_c) * (std_s / std_c) + mean_s, per channel.
__kernel void adain_forward(__global const float* x, __global const float* cmean, __global const float* cstd,
                            __global const float* clo, __global const float* smean, __global const float* sstd,
                            __global float* y, int hw) {
  const int j0 = get_global_id(0) * SPAN;
  const int c = get_global_id(1);
  if (j0 >= hw) return;
  const int end = c * hw + min(j0 + SPAN, hw);
  const float m = cmean[c], lo = clo[c], k = sstd[c] / cstd[c], ms = smean[c];
  int o = c * hw + j0;
  for (; o + 8 <= end; o += 8) vstore8(fma((vload8(0, x + o) - m) - lo, k, ms), 0, y + o);
  for (; o < end; ++o) y[o] = fma((x[o] - m) - lo, k, ms);
}

// dx = dmean / hw + dstd * (x - mean) / (hw * std), the gradient of mean and std = sqrt(var + eps).
// With has_lo, (x - mean) is refined by mean_lo; without it mean_lo is not read.
__kernel void channel_stats_backward(__global const float* x, __global const float* mean,
                                     __global const float* stdv, __global const float* mean_lo,
                                     __global const float* dmean, __global const float* dstd,
                                     __global float* dx, int hw, int has_lo) {
  const int j0 = get_global_id(0) * SPAN;
  const int c = get_global_id(1);
  if (j0 >= hw) return;
  const int end = c * hw + min(j0 + SPAN, hw);
  const float inv_hw = 1.0f / (float)hw;
  const float m = mean[c], lo = has_lo ? mean_lo[c] : 0.0f;
  const float a = dmean[c] * inv_hw, k = dstd[c] * inv_hw / stdv[c];
  int o = c * hw + j0;
  for (; o + 8 <= end; o += 8) vstore8(fma((vload8(0, x + o) - m) - lo, k, a), 0, dx + o);
  for (; o < end; ++o) dx[o] = fma((x[o] - m) - lo, k, a);
}

// Per channel, for the normalisation backward:
//   sdy    = sum(dy)
//   delta  = sum(x - mean) / hw          (the mean's rounding residual, as mean_lo above)
//   sdyhat = sum(dy * xhat), xhat = (x - mean - delta) / std
// using sum(dy * (x - mean - delta)) = sum(dy * (x - mean)) - delta * sdy.

// Over xs[0, n), gs[0, n): *sg = sum(g), *sgx = sum(g * (x - m)), *sx = sum(x - m), blocked as above.
inline void backward_sums(__global const float* xs, __global const float* gs, int n, float m, float* sg_out,
                          float* sgx_out, float* sx_out) {
  const int n8 = n / 8;
  float8 tg = 0.0f, tgx = 0.0f, tx = 0.0f;
  for (int b = 0; b < n8; b += BLOCK) {
    const int e = min(b + BLOCK, n8);
    float8 ag = 0.0f, agx = 0.0f, ax = 0.0f;
    for (int i = b; i < e; ++i) {
      const float8 d = vload8(i, xs) - m;
      const float8 g = vload8(i, gs);
      ag += g;
      agx = fma(g, d, agx);
      ax += d;
    }
    tg += ag;
    tgx += agx;
    tx += ax;
  }
  float sg = hsum8(tg), sgx = hsum8(tgx), sx = hsum8(tx);
  for (int i = n8 * 8; i < n; ++i) {
    const float d = xs[i] - m, g = gs[i];
    sg += g;
    sgx = fma(g, d, sgx);
    sx += d;
  }
  *sg_out = sg;
  *sgx_out = sgx;
  *sx_out = sx;
}

inline void write_backward_sums(int c, float sg, float sgx, float sx, int hw, __global const float* stdv,
                                __global float* sdy_out, __global float* sdyhat_out, __global float* delta_out) {
  const float delta = sx / (float)hw;
  sdy_out[c] = sg;
  sdyhat_out[c] = (sgx - delta * sg) / stdv[c];
  delta_out[c] = delta;
}

__kernel void norm_backward_sums(__global const float* x, __global const float* mean, __global const float* stdv,
                                 __global const float* dy, __global float* sdy_out, __global float* sdyhat_out,
                                 __global float* delta_out, int hw, int nc) {
  const int c = get_global_id(0);
  if (c >= nc) return;
  float sg, sgx, sx;
  backward_sums(x + c * hw, dy + c * hw, hw, mean[c], &sg, &sgx, &sx);
  write_backward_sums(c, sg, sgx, sx, hw, stdv, sdy_out, sdyhat_out, delta_out);
}

// norm_backward_sums over long channels: the three sums per chunk (global (chunks, nc)), then added in
// chunk order (global (nc)).
__kernel void norm_backward_partials(__global const float* x, __global const float* mean, __global const float* dy,
                                     __global float* pg, __global float* pgx, __global float* px, int hw, int chunk,
                                     int chunks) {
  const int k = get_global_id(0), c = get_global_id(1);
  if (k >= chunks) return;
  const long o = (long)c * hw + k * chunk;
  float sg, sgx, sx;
  backward_sums(x + o, dy + o, max(0, min(chunk, hw - k * chunk)), mean[c], &sg, &sgx, &sx);
  pg[c * chunks + k] = sg;
  pgx[c * chunks + k] = sgx;
  px[c * chunks + k] = sx;
}

__kernel void norm_backward_finish(__global const float* pg, __global const float* pgx, __global const float* px,
                                   __global const float* stdv, __global float* sdy_out, __global float* sdyhat_out,
                                   __global float* delta_out, int hw, int chunks, int nc) {
  const int c = get_global_id(0);
  if (c >= nc) return;
  float sg = 0.0f, sgx = 0.0f, sx = 0.0f;
  for (int k = 0; k < chunks; ++k) {
    sg += pg[c * chunks + k];
    sgx += pgx[c * chunks + k];
    sx += px[c * chunks + k];
  }
  write_backward_sums(c, sg, sgx, sx, hw, stdv, sdy_out, sdyhat_out, delta_out);
}

// Instance-norm backward, optionally scaled per channel by gain (AdaIN: gain = std_style):
//   dx = gain / std * (dy - sdy / hw - xhat * sdyhat / hw),  xhat = (x - mean - delta) / std.
// Without has_gain, gain is not read.
__kernel void norm_backward_apply(__global const float* x, __global const float* mean, __global const float* stdv,
                                  __global const float* gain, __global const float* dy,
                                  __global const float* sdy, __global const float* sdyhat,
                                  __global const float* delta, __global float* dx, int hw, int has_gain) {
  const int j0 = get_global_id(0) * SPAN;
  const int c = get_global_id(1);
  if (j0 >= hw) return;
  const int end = c * hw + min(j0 + SPAN, hw);
  const float inv_hw = 1.0f / (float)hw;
  const float s = stdv[c], m = mean[c], dl = delta[c];
  const float k = (has_gain ? gain[c] : 1.0f) / s;  // overall scale
  const float a = sdy[c] * inv_hw;                  // mean of dy
  const float b = sdyhat[c] * inv_hw / s;           // coefficient of (x - mean - delta)
  int o = c * hw + j0;
  for (; o + 8 <= end; o += 8) {
    const float8 xc = (vload8(0, x + o) - m) - dl;
    vstore8(k * (vload8(0, dy + o) - a - xc * b), 0, dx + o);
  }
  for (; o < end; ++o) {
    const float xc = (x[o] - m) - dl;
    dx[o] = k * (dy[o] - a - xc * b);
  }
}
