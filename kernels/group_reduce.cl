// Work-group reductions for GPUs: the first stage of the whole-tensor sums (reduce.cl, loss.cl) and of the
// chunked channel statistics (norm.cl), with the same outputs, so the same finishing kernels follow.
//
// Why: the per-work-item kernels give each work-item a contiguous run of floats, which a CPU streams
// through with vector loads; on a GPU the 32 lanes of a warp then read 32 runs far apart, each load a
// separate memory transaction, and one work-item per chunk is too few to fill the device. Here one
// work-group of WG lanes reduces one chunk: lane l reads elements l, l + WG, ... (neighbouring lanes read
// neighbouring floats), then a tree over __local memory adds the WG lane sums. The order of every
// addition is fixed by the chunk and WG alone, so results are deterministic; each lane's sum has
// chunk / WG terms and the tree log2(WG) levels, so rounding error is smaller than a blocked serial sum.
//
// Launch: global (chunks * WG, rows), local (WG, 1); lib/nn/reduce_path.cpp chooses these kernels.
// Built as the program "norm+group_reduce" (norm.cl first: write_stats and the finishing kernels).

#ifndef WG
#define WG 256
#endif

// Sum over the work-group of each lane's v, in a fixed tree order; every lane gets the result. buf is
// reused by the next call (the closing barrier keeps the next call's writes after this call's reads).
inline float group_sum(float v, local float* buf) {
  const int l = get_local_id(0);
  buf[l] = v;
  barrier(CLK_LOCAL_MEM_FENCE);
  LOCAL_TREE(buf, WG, TREE_ADD)
  const float r = buf[0];
  barrier(CLK_LOCAL_MEM_FENCE);
  return r;
}

// ---- whole-tensor sums: partials[p] over [p * chunk, min((p + 1) * chunk, n)) -------------------------
__kernel __attribute__((reqd_work_group_size(WG, 1, 1))) void sum_partials_group(
    __global const float* x, __global float* partials, int n, int chunk) {
  local float buf[WG];
  float s = 0.0f;
  FOR_CHUNK_ELEMENTS(i, n, chunk, WG) s += x[i];
  s = group_sum(s, buf);
  if (get_local_id(0) == 0) partials[get_group_id(0)] = s;
}

// Stage 1 of mean((a - b)^2).
__kernel __attribute__((reqd_work_group_size(WG, 1, 1))) void sqdiff_partials_group(
    __global const float* a, __global const float* b, __global float* partials, int n, int chunk) {
  local float buf[WG];
  float s = 0.0f;
  FOR_CHUNK_ELEMENTS(i, n, chunk, WG) {
    const float d = a[i] - b[i];
    s = fma(d, d, s);
  }
  s = group_sum(s, buf);
  if (get_local_id(0) == 0) partials[get_group_id(0)] = s;
}

// ---- channel statistics: chunk k of channel c, outputs [nc][chunks] as norm.cl's chunked kernels -------
// The approximate mean m0 is computed once, by channel_mean_group, and read by both the centred sums and
// the finish: the correction mean = m0 + sum(x - m0) / hw is exact only for the very m0 the sums used, and
// a GPU compiler may divide differently in two kernels (an H100 gave m0 one ulp apart: 5% errors in the
// normalised values of a channel with mean 1e4 and std 1e-2).
__kernel __attribute__((reqd_work_group_size(WG, 1, 1))) void channel_sums_group(
    __global const float* x, __global float* psum, int hw, int chunk, int chunks) {
  local float buf[WG];
  const int k = get_group_id(0), c = get_global_id(1), l = get_local_id(0);
  const int j0 = k * chunk, j1 = min(j0 + chunk, hw);
  __global const float* p = x + (long)c * hw;
  float s = 0.0f;
  for (int j = j0 + l; j < j1; j += WG) s += p[j];
  s = group_sum(s, buf);
  if (l == 0) psum[c * chunks + k] = s;
}

// m0[c] = the chunk sums of channel c, added in order, / hw. Global (nc).
__kernel void channel_mean_group(__global const float* psum, __global float* m0, int hw, int chunks, int nc) {
  const int c = get_global_id(0);
  if (c >= nc) return;
  float s = 0.0f;
  for (int k = 0; k < chunks; ++k) s += psum[c * chunks + k];
  m0[c] = s / (float)hw;
}

// Sums of d = x - m0 and d^2 per chunk.
__kernel __attribute__((reqd_work_group_size(WG, 1, 1))) void channel_centred_sums_group(
    __global const float* x, __global const float* m0s, __global float* pd, __global float* pq, int hw, int chunk,
    int chunks) {
  local float buf[WG];
  const int k = get_group_id(0), c = get_global_id(1), l = get_local_id(0);
  const int j0 = k * chunk, j1 = min(j0 + chunk, hw);
  __global const float* p = x + (long)c * hw;
  const float m0 = m0s[c];
  float sd = 0.0f, sq = 0.0f;
  for (int j = j0 + l; j < j1; j += WG) {
    const float d = p[j] - m0;
    sd += d;
    sq = fma(d, d, sq);
  }
  sd = group_sum(sd, buf);
  sq = group_sum(sq, buf);
  if (l == 0) {
    pd[c * chunks + k] = sd;
    pq[c * chunks + k] = sq;
  }
}

// mean, mean_lo and std from the stored m0 and the chunk sums of d and d^2 (norm.cl).
__kernel void channel_stats_finish_group(__global const float* m0s, __global const float* pd, __global const float* pq,
                                         __global float* mean, __global float* stdv, __global float* mean_lo, int hw,
                                         int chunks, float eps, int nc) {
  const int c = get_global_id(0);
  if (c >= nc) return;
  write_stats_from_chunks(c, m0s[c], pd, pq, chunks, hw, eps, mean, stdv, mean_lo);
}

// The normalisation backward's three sums per chunk: sum(dy), sum(dy * (x - mean)), sum(x - mean).
__kernel __attribute__((reqd_work_group_size(WG, 1, 1))) void norm_backward_partials_group(
    __global const float* x, __global const float* mean, __global const float* dy, __global float* pg,
    __global float* pgx, __global float* px, int hw, int chunk, int chunks) {
  local float buf[WG];
  const int k = get_group_id(0), c = get_global_id(1), l = get_local_id(0);
  const int j0 = k * chunk, j1 = min(j0 + chunk, hw);
  const long o = (long)c * hw;
  const float m = mean[c];
  float sg = 0.0f, sgx = 0.0f, sx = 0.0f;
  for (int j = j0 + l; j < j1; j += WG) {
    const float d = x[o + j] - m, g = dy[o + j];
    sg += g;
    sgx = fma(g, d, sgx);
    sx += d;
  }
  sg = group_sum(sg, buf);
  sgx = group_sum(sgx, buf);
  sx = group_sum(sx, buf);
  if (l == 0) {
    pg[c * chunks + k] = sg;
    pgx[c * chunks + k] = sgx;
    px[c * chunks + k] = sx;
  }
}
