// Compositing as two ops (host side: lib/render/weights.cpp and lib/render/composite_values.cpp):
//   1. sigma -> weights over the full sample list: w_i = T_i (1 - exp(-x_i)), plus acc = sum w and
//      depth = sum w t per ray;
//   2. a weighted sum of C-channel values over a COMPACTED list of kept samples: out_r = sum_k w_k v_k,
//      plus the accumulated opacity of the kept samples. It never touches a [samples, C] buffer of all
//      samples, so at C = 256 the cost is that of the kept samples only.
// Gradients flow back the same way: op 2 gives dvalues and dw of the kept samples; the caller adds any
// other dw terms (the full acc, depth, background) and op 1 turns dw into dsigma.
//
// Integer arrays (offsets, counts, ray indices) are I32 tensors (int here).

// Shared with render.cl (kept identical: the two must agree on the weights they produce).
inline float od_of(float sigma, float delta) { return delta > 0.0f ? fmax(sigma * delta, 0.0f) : 0.0f; }
inline float alpha_from(float x, float e) {
  return x < 1e-2f ? x * (1.0f - 0.5f * x * (1.0f - x * (1.0f / 3.0f))) : 1.0f - e;
}
inline float dod_dsigma(float sigma, float delta) { return (delta > 0.0f && sigma >= 0.0f) ? delta : 0.0f; }

// ---- op 1: sigma -> weights ---------------------------------------------------------------------------
kernel void weights_forward(global const float* sigma, global const float* deltas, global const float* tvals,
                            global const int* offsets, global const int* counts, int R, global float* weights,
                            global float* acc_out, global float* depth_out) {
  const int r = get_global_id(0);
  if (r >= R) return;
  const int off = offsets[r], cnt = counts[r];
  float T = 1.0f, acc = 0.0f, depth = 0.0f;
  for (int k = off; k < off + cnt; ++k) {
    const float x = od_of(sigma[k], deltas[k]);
    const float e = exp(-x);
    const float w = T * alpha_from(x, e);
    T *= e;
    acc += w;
    depth = fma(w, tvals[k], depth);
    weights[k] = w;
  }
  acc_out[r] = acc;
  depth_out[r] = depth;
}

// With v_i = dw_i + dacc_r + ddepth_r t_i (the full gradient of the loss w.r.t. w_i):
//   dL/dx_k = v_k T_{k+1} - sum_{i>k} v_i w_i,   dsigma_k = dL/dx_k * dx_k/dsigma_k.
// Two passes over the ray: the first totals sum v_i w_i, the second subtracts the running prefix.
kernel void weights_backward(global const float* sigma, global const float* deltas, global const float* tvals,
                             global const int* offsets, global const int* counts, int R, global const float* dw,
                             int has_dw, global const float* dacc, int has_dacc, global const float* ddepth,
                             int has_ddepth, global float* dsigma) {
  const int r = get_global_id(0);
  if (r >= R) return;
  const int off = offsets[r], cnt = counts[r];
  const float da = has_dacc ? dacc[r] : 0.0f, dd = has_ddepth ? ddepth[r] : 0.0f;
  float T = 1.0f, total = 0.0f;
  for (int k = off; k < off + cnt; ++k) {
    const float x = od_of(sigma[k], deltas[k]);
    const float e = exp(-x);
    const float w = T * alpha_from(x, e);
    T *= e;
    const float v = (has_dw ? dw[k] : 0.0f) + da + dd * tvals[k];
    total = fma(v, w, total);
  }
  T = 1.0f;
  float prefix = 0.0f;
  for (int k = off; k < off + cnt; ++k) {
    const float s = sigma[k], dl = deltas[k];
    const float x = od_of(s, dl);
    const float e = exp(-x);
    const float w = T * alpha_from(x, e);
    const float Tn = T * e;
    const float v = (has_dw ? dw[k] : 0.0f) + da + dd * tvals[k];
    prefix = fma(v, w, prefix);
    dsigma[k] = (v * Tn - (total - prefix)) * dod_dsigma(s, dl);
    T = Tn;
  }
}

// ---- op 2: weighted sum of C-channel values over kept samples ---------------------------------------------
// VW (a build option) is the vector width over channels: 16, 8, 4 or 1; the host picks the largest that
// divides C. One work-item handles one ray (or one kept sample) and VW consecutive channels.
#ifndef VW
#define VW 1
#endif
#define CAT_(a, b) a##b
#define CAT(a, b) CAT_(a, b)
#if VW == 1
#define VT float
#define VLOAD(i, p) ((p)[i])
#define VSTORE(v, i, p) ((p)[i] = (v))
#define VSUM(v) (v)
#else
#define VT CAT(float, VW)
#define VLOAD(i, p) CAT(vload, VW)(i, p)
#define VSTORE(v, i, p) CAT(vstore, VW)(v, i, p)
#endif
#if VW == 4
#define VSUM(v) ((v).s0 + (v).s1 + (v).s2 + (v).s3)
#elif VW == 8
#define VSUM(v) (((v).s0 + (v).s1) + ((v).s2 + (v).s3) + ((v).s4 + (v).s5) + ((v).s6 + (v).s7))
#elif VW == 16
#define VSUM(v) (VSUM8((v).lo) + VSUM8((v).hi))
#define VSUM8(v) (((v).s0 + (v).s1) + ((v).s2 + (v).s3) + ((v).s4 + (v).s5) + ((v).s6 + (v).s7))
#endif

// out[r, chunk] = sum_{k in ray r} w[k] * vals[row_k, chunk], row_k = rows[k] when indexed, else k; chunk 0
// also writes acc[r] = sum w[k].
inline void weighted_row_sum(global const float* w, global const float* vals, global const int* rows, int indexed,
                             global const int* offsets, global const int* counts, int R, int C, global float* out,
                             global float* acc_out) {
  const int r = get_global_id(0), ch = get_global_id(1);
  const int chunks = C / VW;
  if (r >= R || ch >= chunks) return;
  const int off = offsets[r], cnt = counts[r];
  VT s = (VT)(0.0f);
  float acc = 0.0f;
  for (int k = off; k < off + cnt; ++k) {
    const float wk = w[k];
    const long row = indexed ? rows[k] : k;
    s = fma((VT)(wk), VLOAD(ch, vals + row * C), s);
    acc += wk;
  }
  VSTORE(s, ch, out + (long)r * C);
  if (ch == 0) acc_out[r] = acc;
}

kernel void values_forward(global const float* w, global const float* vals, global const int* offsets,
                           global const int* counts, int R, int C, global float* out, global float* acc_out) {
  weighted_row_sum(w, vals, offsets, 0, offsets, counts, R, C, out, acc_out);
}

// The same sum with entry k's value row vals[rows[k]] (a gather fused into the sum: the grouped
// renderer's weighted mean of each merged point's members, lib/model/ray_pipeline.cpp; inference only).
kernel void values_forward_indexed(global const float* w, global const float* vals, global const int* rows,
                                   global const int* offsets, global const int* counts, int R, int C,
                                   global float* out, global float* acc_out) {
  weighted_row_sum(w, vals, rows, 1, offsets, counts, R, C, out, acc_out);
}

// dvals[k, chunk] = w[k] * dout[ray[k], chunk].
kernel void values_backward_dvalues(global const float* w, global const int* ray_of, int K, int C,
                                    global const float* dout, global float* dvals) {
  const int k = get_global_id(0), ch = get_global_id(1);
  if (k >= K || ch >= C / VW) return;
  VSTORE((VT)(w[k]) * VLOAD(ch, dout + (long)ray_of[k] * C), ch, dvals + (long)k * C);
}

// dw[k] = <dout[ray[k]], vals[k]> + dacc[ray[k]] (dout / dacc optional).
kernel void values_backward_dweights(global const float* vals, global const int* ray_of, int K, int C,
                                     global const float* dout, int has_dout, global const float* dacc, int has_dacc,
                                     global float* dw) {
  const int k = get_global_id(0);
  if (k >= K) return;
  const int r = ray_of[k];
  float s = has_dacc ? dacc[r] : 0.0f;
  if (has_dout) {
    const global float* v = vals + (long)k * C;
    const global float* d = dout + (long)r * C;
    VT a = (VT)(0.0f);
    for (int ch = 0; ch < C / VW; ++ch) a = fma(VLOAD(ch, v), VLOAD(ch, d), a);
    s += VSUM(a);
  }
  dw[k] = s;
}

// ---- background -------------------------------------------------------------------------------------------
// out[r, c] += (1 - acc[r]) * bg[c]  (in place).
kernel void background_forward(global float* out, global const float* acc, global const float* bg, int R, int C) {
  const int r = get_global_id(0);
  if (r >= R) return;
  const float t = 1.0f - acc[r];
  for (int c = 0; c < C; ++c) out[(long)r * C + c] = fma(t, bg[c], out[(long)r * C + c]);
}

// dacc[r] (+)= -<dout[r], bg>  (accumulate: has_prev adds to what is there).
kernel void background_backward(global const float* dout, global const float* bg, int R, int C, global float* dacc,
                                int accumulate) {
  const int r = get_global_id(0);
  if (r >= R) return;
  float s = 0.0f;
  for (int c = 0; c < C; ++c) s = fma(dout[(long)r * C + c], bg[c], s);
  dacc[r] = (accumulate ? dacc[r] : 0.0f) - s;
}

// ---- deferred shading: per-ray normalisation by opacity, and scaling by it -------------------------------
// A deferred head shades the weighted mean of a ray's features once, c = f(F / (a + eps)), and returns a c:
// equal to per-sample shading sum_i w_i f(x_i) when one sample carries the ray's weight (a hard surface),
// one network evaluation per ray instead of per sample. F [R, C] composited features, a [R] their opacity
// (lib/render/deferred.hpp).

// n[r, :] = F[r, :] / (a[r] + eps)
kernel void opacity_normalise_forward(global const float* F, global const float* a, int R, int C, float eps,
                                      global float* n) {
  const int r = get_global_id(0);
  if (r >= R) return;
  const float inv = 1.0f / (fmax(a[r], 0.0f) + eps);
  for (int c = 0; c < C; ++c) n[(long)r * C + c] = F[(long)r * C + c] * inv;
}

// dF = dn / (a + eps);  da[r] += -sum_c dn[r, c] F[r, c] / (a + eps)^2  (da accumulates; 0 where a < 0,
// which the forward clamps).
kernel void opacity_normalise_backward(global const float* F, global const float* a, global const float* dn, int R,
                                       int C, float eps, global float* dF, global float* da) {
  const int r = get_global_id(0);
  if (r >= R) return;
  const float inv = 1.0f / (fmax(a[r], 0.0f) + eps);
  float s = 0.0f;
  for (int c = 0; c < C; ++c) {
    const long k = (long)r * C + c;
    dF[k] = dn[k] * inv;
    s = fma(dn[k], F[k], s);
  }
  if (a[r] >= 0.0f) da[r] -= s * inv * inv;
}

// y[r, :] = a[r] * c[r, :]
kernel void opacity_scale_forward(global const float* c, global const float* a, int R, int C, global float* y) {
  const int r = get_global_id(0);
  if (r >= R) return;
  for (int j = 0; j < C; ++j) y[(long)r * C + j] = a[r] * c[(long)r * C + j];
}

// dc = a dy;  da[r] += sum_j dy[r, j] c[r, j]  (da accumulates).
kernel void opacity_scale_backward(global const float* c, global const float* a, global const float* dy, int R, int C,
                                   global float* dc, global float* da) {
  const int r = get_global_id(0);
  if (r >= R) return;
  float s = 0.0f;
  for (int j = 0; j < C; ++j) {
    const long k = (long)r * C + j;
    dc[k] = a[r] * dy[k];
    s = fma(dy[k], c[k], s);
  }
  da[r] += s;
}

// The distortion loss of a ray's weights (Mip-NeRF 360, Barron et al. 2022), each sample an interval of
// length d centred at u_i = t_i * inv_len (samples in increasing t along the ray):
//   L_r = sum_i sum_j w_i w_j |u_i - u_j| + (d / 3) sum_i w_i^2,   dL/dw_i = 2 s_i + (2 d / 3) w_i,
// s_i = sum_j w_j |u_i - u_j| = u_i W_<i - M_<i + M_>i - u_i W_>i (W, M: the sums of w and w u before / after
// i). Two passes: the totals, then the running prefix. Both scaled by `scale`.
kernel void distortion_forward_backward(global const float* weights, global const float* tvals,
                                        global const int* offsets, global const int* counts, int R, float inv_len,
                                        float d, float scale, global float* loss, global float* dw) {
  const int r = get_global_id(0);
  if (r >= R) return;
  const int off = offsets[r], cnt = counts[r];
  float W = 0.0f, M = 0.0f;
  for (int k = off; k < off + cnt; ++k) {
    W += weights[k];
    M = fma(weights[k], tvals[k] * inv_len, M);
  }
  float Wb = 0.0f, Mb = 0.0f, L = 0.0f;
  for (int k = off; k < off + cnt; ++k) {
    const float w = weights[k], u = tvals[k] * inv_len;
    const float Wa = W - Wb - w, Ma = M - Mb - w * u;
    const float s = u * Wb - Mb + Ma - u * Wa;
    L += w * s + (d / 3.0f) * w * w;
    dw[k] = scale * (2.0f * s + (2.0f * d / 3.0f) * w);
    Wb += w;
    Mb = fma(w, u, Mb);
  }
  loss[r] = scale * L;
}
