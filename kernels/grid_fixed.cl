// The VM grids' backward scatter in 64-bit fixed point: deterministic without float atomics.
// Built as the program "grid+grid_fixed" (grid.cl first, for the layout, taps and activations), only on
// devices that report cl_khr_int64_base_atomics (lib/field/vm_grid.cpp checks).
//
// Why fixed point: a float atomic add's result depends on the order the adds arrive in, and OpenCL 1.2
// has no float atomics at all (the compare-and-swap loop this replaced retried whenever another
// work-item wrote the cell in between: on an H100, with many samples per texel, that loop was 6.11 s of
// a 6.22 s paper stage-2 step; this scatter takes 40 ms there). Integer addition is exact and associative, so the sum of integers does not depend on the
// order, and an integer atomic add never retries.
//
// One call of the scatter:
//   1. vm_fixed_bound_partials + vm_fixed_scale: an exponent s with n * max|g| * max|params| * 2^s
//      <= 2^62, where g is the per-point gradient (dsig or a dfeat row). A point adds to a grid element
//      at most once, with |contribution| <= max|g| * max|params| (taps interpolate, weights <= 1), so no
//      element's sum can leave the 64-bit range.
//   2. vm_scatter_fixed: one work-item per (point, feature component): each contribution c becomes
//      round(c * 2^s) and is added to an int64 accumulator with atom_add.
//   3. vm_fixed_finish: dgrid += acc * 2^-s (one rounding to float), and the accumulator is zeroed for
//      the next call.
// Precision: each contribution is exact to 2^-s, i.e. to about 2^-40 of the largest possible one when n
// is a few million; the sum is exact and is rounded once. A float scatter instead rounds at every add.
// A non-finite contribution (or bound) cannot be carried by an integer: it sets a flag, and the finish
// then writes NaN into the whole gradient, so it is seen rather than dropped.

#pragma OPENCL EXTENSION cl_khr_int64_base_atomics : enable

inline bool fixed_nonfinite(float x) { return (as_uint(x) & 0x7f800000u) == 0x7f800000u; }

// partials[p] = max |x| over x[p*chunk, min((p+1)*chunk, n)); +inf if any element there is not finite.
// One work-group of BOUND_WG lanes per chunk, lane l reading elements l, l + BOUND_WG, ... (neighbouring
// lanes, neighbouring floats: on a GPU a bound over 3 GB of dfeat is then a millisecond, not the 60-150 ms
// a work-item per contiguous chunk took), then a max tree over __local memory. max is exact, so the order
// does not matter.
#define BOUND_WG 256
kernel __attribute__((reqd_work_group_size(BOUND_WG, 1, 1))) void vm_fixed_bound_partials(
    global const float* x, global float* partials, int n, int chunk) {
  local float buf[BOUND_WG];
  const int l = get_local_id(0);
  float m = 0.0f;
  bool bad = false;
  FOR_CHUNK_ELEMENTS(i, n, chunk, BOUND_WG) {
    const float v = x[i];
    bad |= fixed_nonfinite(v);
    m = fmax(m, fabs(v));
  }
  buf[l] = bad ? INFINITY : m;
  barrier(CLK_LOCAL_MEM_FENCE);
  LOCAL_TREE(buf, BOUND_WG, fmax)
  if (l == 0) partials[get_group_id(0)] = buf[0];
}

// One work-item. state[0] = s, state[1] = 0, or state[1] = 1 when a bound is not finite.
// frexp gives each factor < 2^e, so the product is < 2^(eg + ep + en): no float overflow on the way.
kernel void vm_fixed_scale(global const float* gpart, int ng, global const float* ppart, int np, int npoints,
                           global int* state) {
  if (get_global_id(0) != 0) return;
  float mg = 0.0f, mp = 0.0f;
  for (int k = 0; k < ng; ++k) mg = fmax(mg, gpart[k]);
  for (int k = 0; k < np; ++k) mp = fmax(mp, ppart[k]);
  state[0] = 0;
  state[1] = 0;
  if (fixed_nonfinite(mg) || fixed_nonfinite(mp)) {
    state[1] = 1;
    return;
  }
  if (mg == 0.0f || mp == 0.0f) return;  // every contribution is zero: nothing is added
  int eg, ep, en;
  frexp(mg, &eg);
  frexp(mp, &ep);
  frexp((float)npoints, &en);
  state[0] = 62 - (eg + ep + en);
}

// acc[k] += round(c * 2^s); a non-finite c raises the flag instead.
inline void add_fixed(volatile global ulong* acc, float c, int s, volatile global int* flag) {
  if (c == 0.0f) return;
  if (fixed_nonfinite(c)) {
    atomic_or(flag, 1);
    return;
  }
  atom_add(acc, as_ulong(convert_long_rte(ldexp(c, s))));
}

// Work-item j = point i * nfeat + component q (q = feat_off[m] + r: mode m, rank r), so the work-items of a
// point are adjacent and their adds go to adjacent texel elements. mode 0: density (dsig [n], sigma [n],
// one gradient for every rank); mode 1: features (dsig is dfeat [n, nfeat]).
kernel void vm_scatter_fixed(global const float* pts, global const float* grid, global const float* dsig,
                             global const float* sigma, global ulong* acc, global int* state, int n, int rx, int ry,
                             int rz, int r0, int r1, int r2, int mode, int act) {
  const VMLayout L = vm_layout(rx, ry, rz, r0, r1, r2);
  const long j = get_global_id(0);
  if (j >= (long)n * L.nfeat) return;
  const int i = (int)(j / L.nfeat), q = (int)(j - (long)i * L.nfeat);
  const float3 p = vload3(i, pts);
  if (!inside_box(p)) return;
  const float g = mode == 0 ? dsig[i] * density_act_grad(sigma[i], act) : dsig[j];
  if (g == 0.0f) return;  // NaN is not equal to 0: it goes on and raises the flag
  const int m = q < L.feat_off[1] ? 0 : (q < L.feat_off[2] ? 1 : 2);
  const int r = q - L.feat_off[m];
  PointCell c;
  point_cell(&L, p, &c);
  ModeTaps T;
  cell_taps(&L, &c, m, &T);
  const float gp = g * line1(grid, &T, r), gl = g * plane1(grid, &T, r);
  const int s = state[0];
  volatile global int* flag = state + 1;
  for (int k = 0; k < 4; ++k)
    if (T.pw[k] != 0.0f) add_fixed(acc + T.pt[k] + r, gp * T.pw[k], s, flag);
  for (int k = 0; k < 2; ++k)
    if (T.lw[k] != 0.0f) add_fixed(acc + T.lt[k] + r, gl * T.lw[k], s, flag);
}

// dgrid[k] += acc[k] * 2^-s, then acc[k] = 0; NaN everywhere when the flag is up.
kernel void vm_fixed_finish(global ulong* acc, global float* dgrid, global const int* state, int numel) {
  const int k = get_global_id(0);
  if (k >= numel) return;
  if (state[1] != 0) {
    dgrid[k] = NAN;
  } else {
    const long v = as_long(acc[k]);
    if (v != 0) dgrid[k] += ldexp(convert_float_rte(v), -state[0]);
  }
  acc[k] = 0;
}

kernel void vm_fixed_zero(global ulong* acc, int numel) {
  const int k = get_global_id(0);
  if (k < numel) acc[k] = 0;
}
