// Ray marching that evaluates the density as it goes, for early ray termination: a ray stops at the
// first sample after which its transmittance is below a threshold. Built as the program
// "grid+render+march_density" (the three files concatenated, with grid.cl's -DRANKn options): it uses the
// march walk of render.cl and the VM density of grid.cl, so a sample's sigma here is the one
// vm_density_forward gives at the same point, bit for bit.
//
// Pass 1 (march_density_count): per ray, walk the candidates (alpha-mask skip as in march_count),
// evaluate sigma at each kept one into a per-ray staging row [R][cap], and stop after the sample that
// brings T = exp(-sum sigma delta) below ert_thr. counts[r] = samples written.
// Pass 2 is render.cl's march_write, which stops at counts[r]; then stage_compact moves each ray's staged
// sigmas to the compacted sample list. Density is evaluated once per sample that is kept, and never for
// the samples behind the termination point.
// Samples beyond the stop have weight w_i <= T_i < ert_thr: with ert_thr at most the keep threshold they
// would get no value anyway, and their only effect is an opacity change below ert_thr.

kernel void march_density_count(MARCH_ARGS, global const float* grid, int rx, int ry, int rz, int r0, int r1, int r2,
                                int act, float delta_scale, float ert_thr, int cap, global float* staged,
                                global int* counts) {
  const int r = get_global_id(0);
  if (r >= R) return;
  const MarchParams P = march_params(lox, loy, loz, hix, hiy, hiz, near, far, step, max_samples);
  const VMLayout L = vm_layout(rx, ry, rz, r0, r1, r2);
  const float3 o = vload3(r, origins), d = vload3(r, dirs);
  const float jitter = jitter_on ? hash_uniform(seed, ray_base + (uint)r) : 0.0f;
  const float delta = P.step * length(d) * delta_scale;
  float t0;
  const int n = min(ray_candidates(&P, o, d, jitter, &t0), cap);
  const MaskWalk W = mask_walk(&P, o, d, mx, my, mz);
  global float* row = staged + (long)r * cap;
  // Optical depth, summed: T = exp(-tau) < thr  <=>  tau > -log(thr), with no per-sample exp.
  const float tau_stop = -log(ert_thr);
  float tau = 0.0f;
  int c = 0;
  for (int i = 0; i < n; ++i) {
    const float t = t0 + P.step * ((float)i + jitter);
    if (has_mask && !occupied_at(mask, &W, t)) continue;
    const float3 q = normalised_at(&P, o, d, t);
    const float sigma = inside_box(q) ? density_act(density_at(grid, &L, q), act) : 0.0f;  // as vm_density_forward
    row[c++] = sigma;
    // As the compositing does: a negative or NaN sigma adds no optical depth.
    if (sigma > 0.0f) tau += sigma * delta;
    if (tau > tau_stop) break;
  }
  counts[r] = c;
}

// sigma[offsets[r] + j] = staged[r][j] for j < counts[r].
kernel void stage_compact(global const float* staged, global const int* offsets, global const int* counts, int R,
                          int cap, global float* sigma) {
  const int r = get_global_id(0);
  if (r >= R) return;
  const global float* row = staged + (long)r * cap;
  global float* out = sigma + offsets[r];
  for (int j = 0; j < counts[r]; ++j) out[j] = row[j];
}
