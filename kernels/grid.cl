// TensoRF vector-matrix (VM) grids: sampling forward/backward, TV and L1 regularisers, resampling to a
// new resolution, alpha-mask construction, and the appearance head's small elementwise steps.
//
// Parameter layout (one flat float buffer per grid; see lib/field/vm_grid.hpp):
//   [plane0][plane1][plane2][line0][line1][line2]
//   mode m: plane axes (u, v) = (0,1), (0,2), (1,2); line axis w = 2, 1, 0 (TensoRF's matMode/vecMode);
//   plane m is [n_v][n_u][R_m] and line m is [n_w][R_m]: the rank is innermost, so the R values of one
//   bilinear tap are one contiguous run (vload4 over the rank, no gather).
// Sampling follows grid_sample(align_corners=True): p = -1 -> index 0, p = +1 -> index n-1. Points with
// any coordinate outside [-1,1] (or NaN) are outside the box: zero density/features and no gradient.
// Grids have n >= 2 along every axis (checked on the host).

// ---- layout ---------------------------------------------------------------------------------------
typedef struct {
  int res[3];
  int rank[3];
  int plane_off[3];
  int line_off[3];
  int feat_off[3];  // offset of mode m's components in the concatenated feature vector
  int nfeat;
  int numel;
} VMLayout;

// The host builds each grid's program with -DRANK0=.. -DRANK1=.. -DRANK2=.. (lib/field/vm_grid.cpp): the
// rank loops then have constant trip counts and unroll into straight vector loads; the int arguments are
// kept for the layout check and for builds without the macros.
inline VMLayout vm_layout(int rx, int ry, int rz, int r0, int r1, int r2) {
#ifdef RANK0
  r0 = RANK0;
  r1 = RANK1;
  r2 = RANK2;
#endif
  VMLayout L;
  L.res[0] = rx; L.res[1] = ry; L.res[2] = rz;
  L.rank[0] = r0; L.rank[1] = r1; L.rank[2] = r2;
  const int p0 = ry * rx * r0, p1 = rz * rx * r1, p2 = rz * ry * r2;
  L.plane_off[0] = 0; L.plane_off[1] = p0; L.plane_off[2] = p0 + p1;
  L.line_off[0] = p0 + p1 + p2;
  L.line_off[1] = L.line_off[0] + rz * r0;
  L.line_off[2] = L.line_off[1] + ry * r1;
  L.numel = L.line_off[2] + rx * r2;
  L.feat_off[0] = 0; L.feat_off[1] = r0; L.feat_off[2] = r0 + r1;
  L.nfeat = r0 + r1 + r2;
  return L;
}

inline int mode_u(int m) { return m == 2 ? 1 : 0; }
inline int mode_v(int m) { return m == 0 ? 1 : 2; }
inline int mode_w(int m) { return 2 - m; }

inline bool inside_box(float3 p) {
  // Written so that NaN compares false and counts as outside.
  return p.x >= -1.0f && p.x <= 1.0f && p.y >= -1.0f && p.y <= 1.0f && p.z >= -1.0f && p.z <= 1.0f;
}

inline float coord(float3 p, int axis) { return axis == 0 ? p.x : (axis == 1 ? p.y : p.z); }

// Align-corners coordinate -> lower tap index in [0, n-2] and fraction in [0,1] (p = +1 gives n-2, 1).
inline int corner_index(float p, int n, float* frac) {
  const float f = (p + 1.0f) * 0.5f * (float)(n - 1);
  const int i = clamp((int)floor(f), 0, n - 2);
  *frac = clamp(f - (float)i, 0.0f, 1.0f);
  return i;
}

// Taps of one mode at point p: 4 plane taps and 2 line taps (element offsets of rank 0) and weights.
typedef struct {
  int pt[4];
  float pw[4];
  int lt[2];
  float lw[2];
  int R;
} ModeTaps;

inline ModeTaps mode_taps(const VMLayout* L, int m, float3 p) {
  ModeTaps T;
  const int u = mode_u(m), v = mode_v(m), w = mode_w(m);
  const int nu = L->res[u], nv = L->res[v], nw = L->res[w], R = L->rank[m];
  float fu, fv, fw;
  const int iu = corner_index(coord(p, u), nu, &fu);
  const int iv = corner_index(coord(p, v), nv, &fv);
  const int iw = corner_index(coord(p, w), nw, &fw);
  const int base = L->plane_off[m] + (iv * nu + iu) * R;
  T.pt[0] = base;           T.pw[0] = (1.0f - fu) * (1.0f - fv);
  T.pt[1] = base + R;       T.pw[1] = fu * (1.0f - fv);
  T.pt[2] = base + nu * R;  T.pw[2] = (1.0f - fu) * fv;
  T.pt[3] = base + nu * R + R; T.pw[3] = fu * fv;
  T.lt[0] = L->line_off[m] + iw * R; T.lw[0] = 1.0f - fw;
  T.lt[1] = T.lt[0] + R;             T.lw[1] = fw;
  T.R = R;
  return T;
}

inline float4 plane4(const global float* g, const ModeTaps* T, int r) {
  float4 a = T->pw[0] * vload4(0, g + T->pt[0] + r);
  a = fma((float4)(T->pw[1]), vload4(0, g + T->pt[1] + r), a);
  a = fma((float4)(T->pw[2]), vload4(0, g + T->pt[2] + r), a);
  return fma((float4)(T->pw[3]), vload4(0, g + T->pt[3] + r), a);
}
inline float4 line4(const global float* g, const ModeTaps* T, int r) {
  return fma((float4)(T->lw[1]), vload4(0, g + T->lt[1] + r), T->lw[0] * vload4(0, g + T->lt[0] + r));
}
inline float plane1(const global float* g, const ModeTaps* T, int r) {
  return T->pw[0] * g[T->pt[0] + r] + T->pw[1] * g[T->pt[1] + r] + T->pw[2] * g[T->pt[2] + r] +
         T->pw[3] * g[T->pt[3] + r];
}
inline float line1(const global float* g, const ModeTaps* T, int r) {
  return T->lw[0] * g[T->lt[0] + r] + T->lw[1] * g[T->lt[1] + r];
}

// ---- density activation ------------------------------------------------------------------------------
// act 0: relu(f); act 1: softplus(f - 10) (TensoRF's density shift). Both derivatives are functions of the
// output alone (relu: sigma > 0; softplus: sigmoid(f - 10) = 1 - exp(-sigma)), so backward needs only sigma.
inline float density_act(float f, int act) {
  if (act == 0) return fmax(f, 0.0f);
  const float x = f - 10.0f;
  return fmax(x, 0.0f) + log1p(exp(-fabs(x)));
}
inline float density_act_grad(float sigma, int act) {
  if (act == 0) return sigma > 0.0f ? 1.0f : 0.0f;
  return -expm1(-sigma);
}

inline float density_at(const global float* g, const VMLayout* L, float3 p) {
  float acc = 0.0f;
  for (int m = 0; m < 3; ++m) {
    const ModeTaps T = mode_taps(L, m, p);
    float4 s = (float4)(0.0f);
    int r = 0;
    for (; r + 4 <= T.R; r += 4) {
      s = fma(plane4(g, &T, r), line4(g, &T, r), s);
    }
    acc += s.x + s.y + s.z + s.w;
    for (; r < T.R; ++r) acc += plane1(g, &T, r) * line1(g, &T, r);
  }
  return acc;
}

// ---- sampling forward ------------------------------------------------------------------------------
// pts [n,3] normalised to [-1,1]^3 -> sigma [n] = act(sum_m sum_r plane_m[r] * line_m[r]).
kernel void vm_density_forward(global const float* pts, global const float* grid, global float* sigma, int n, int rx,
                               int ry, int rz, int r0, int r1, int r2, int act) {
  const int i = get_global_id(0);
  if (i >= n) return;
  const float3 p = vload3(i, pts);
  if (!inside_box(p)) {
    sigma[i] = 0.0f;
    return;
  }
  const VMLayout L = vm_layout(rx, ry, rz, r0, r1, r2);
  sigma[i] = density_act(density_at(grid, &L, p), act);
}

// pts [n,3] -> feat [n, r0+r1+r2] = concat_m(plane_m[r] * line_m[r]).
kernel void vm_features_forward(global const float* pts, global const float* grid, global float* feat, int n, int rx,
                                int ry, int rz, int r0, int r1, int r2) {
  const int i = get_global_id(0);
  if (i >= n) return;
  const VMLayout L = vm_layout(rx, ry, rz, r0, r1, r2);
  global float* out = feat + (long)i * L.nfeat;
  const float3 p = vload3(i, pts);
  if (!inside_box(p)) {
    for (int k = 0; k < L.nfeat; ++k) out[k] = 0.0f;
    return;
  }
  for (int m = 0; m < 3; ++m) {
    const ModeTaps T = mode_taps(&L, m, p);
    global float* o = out + L.feat_off[m];
    int r = 0;
    for (; r + 4 <= T.R; r += 4) {
      vstore4(plane4(grid, &T, r) * line4(grid, &T, r), 0, o + r);
    }
    for (; r < T.R; ++r) o[r] = plane1(grid, &T, r) * line1(grid, &T, r);
  }
}

// ---- sampling backward (scatter) --------------------------------------------------------------------------
// OpenCL 1.2 has no float atomics: compare-and-swap on the int bits.
inline void atomic_add_f(volatile global float* addr, float val) {
  union {
    unsigned int u;
    float f;
  } old, nxt;
  do {
    old.f = *addr;
    nxt.f = old.f + val;
  } while (atomic_cmpxchg((volatile global unsigned int*)addr, old.u, nxt.u) != old.u);
}

inline void add_to(global float* g, int idx, float v, int use_atomic) {
  if (use_atomic)
    atomic_add_f(g + idx, v);
  else
    g[idx] += v;
}

// Scatters one point's gradient. gfeat points at the point's d(feature) values: component (m, r) has
// gradient gfeat[(feat_off[m] + r) * gstep] (gstep 0: one value for every component, the density case).
inline void scatter_point(const global float* grid, global float* dgrid, const VMLayout* L, float3 p,
                          const global float* gfeat, int gstep, float gscale, int use_atomic) {
  for (int m = 0; m < 3; ++m) {
    const ModeTaps T = mode_taps(L, m, p);
    for (int r = 0; r < T.R; ++r) {
      const float g = gscale * gfeat[(L->feat_off[m] + r) * gstep];
      if (g == 0.0f) continue;
      const float pv = plane1(grid, &T, r), lv = line1(grid, &T, r);
      const float gp = g * lv, gl = g * pv;
      for (int k = 0; k < 4; ++k)
        if (T.pw[k] != 0.0f) add_to(dgrid, T.pt[k] + r, gp * T.pw[k], use_atomic);
      for (int k = 0; k < 2; ++k)
        if (T.lw[k] != 0.0f) add_to(dgrid, T.lt[k] + r, gl * T.lw[k], use_atomic);
    }
  }
}

// The gradient source of point i: density (dsigma and sigma: activation derivative folded into gscale)
// or features (dfeat rows).
inline int point_grad(int i, int mode, const global float* dsigma_or_dfeat, const global float* sigma, int nfeat,
                      int act, const global float** gfeat, int* gstep, float* gscale) {
  if (mode == 0) {
    *gfeat = dsigma_or_dfeat + i;
    *gstep = 0;
    *gscale = density_act_grad(sigma[i], act);
  } else {
    *gfeat = dsigma_or_dfeat + (long)i * nfeat;
    *gstep = 1;
    *gscale = 1.0f;
  }
  return 0;
}

// One work-item per point, atomic adds into dgrid (accumulates). mode 0: density (dsig [n], sigma [n]);
// mode 1: features (dsig is dfeat [n, nfeat], sigma unused).
kernel void vm_scatter_atomic(global const float* pts, global const float* grid, global const float* dsig,
                              global const float* sigma, global float* dgrid, int n, int rx, int ry, int rz, int r0,
                              int r1, int r2, int mode, int act) {
  const int i = get_global_id(0);
  if (i >= n) return;
  const float3 p = vload3(i, pts);
  if (!inside_box(p)) return;
  const VMLayout L = vm_layout(rx, ry, rz, r0, r1, r2);
  const global float* gf;
  int gstep;
  float gscale;
  point_grad(i, mode, dsig, sigma, L.nfeat, act, &gf, &gstep, &gscale);
  if (gscale == 0.0f) return;
  scatter_point(grid, dgrid, &L, p, gf, gstep, gscale, 1);
}

// Deterministic privatised scatter: work-item c (of `copies`) handles points [c*chunk, (c+1)*chunk) in
// order with plain adds into its own copy: copy 0 is dgrid itself (accumulates), copies 1.. live in
// scratch ((copies-1) * numel floats, zeroed here) and are summed into dgrid by vm_reduce_copies.
kernel void vm_scatter_private(global const float* pts, global const float* grid, global const float* dsig,
                               global const float* sigma, global float* dgrid, global float* scratch, int n, int chunk,
                               int rx, int ry, int rz, int r0, int r1, int r2, int mode, int act) {
  const int c = get_global_id(0);
  const VMLayout L = vm_layout(rx, ry, rz, r0, r1, r2);
  global float* dst = c == 0 ? dgrid : scratch + (long)(c - 1) * L.numel;
  if (c > 0)
    for (int k = 0; k < L.numel; ++k) dst[k] = 0.0f;
  const int begin = c * chunk, end = min(n, begin + chunk);
  for (int i = begin; i < end; ++i) {
    const float3 p = vload3(i, pts);
    if (!inside_box(p)) continue;
    const global float* gf;
    int gstep;
    float gscale;
    point_grad(i, mode, dsig, sigma, L.nfeat, act, &gf, &gstep, &gscale);
    if (gscale == 0.0f) continue;
    scatter_point(grid, dst, &L, p, gf, gstep, gscale, 0);
  }
}

// dgrid[k] += sum_c scratch[c][k], copies in a fixed order (deterministic).
kernel void vm_reduce_copies(global const float* scratch, global float* dgrid, int numel, int ncopies) {
  const int k = get_global_id(0);
  if (k >= numel) return;
  float s = dgrid[k];
  for (int c = 0; c < ncopies; ++c) s += scratch[(long)c * numel + k];
  dgrid[k] = s;
}

// ---- regularisers ------------------------------------------------------------------------------------
// TV over the planes: sum_m [ sum (P[v+1][u] - P[v][u])^2 / (R (nv-1) nu) + sum (P[v][u+1] - P[v][u])^2 /
// (R nv (nu-1)) ]. Forward: one work-item per plane row (m, v) writes its share; the host sums in double.
inline int row_mode(const VMLayout* L, int row, int* v) {
  for (int m = 0; m < 3; ++m) {
    const int nv = L->res[mode_v(m)];
    if (row < nv) {
      *v = row;
      return m;
    }
    row -= nv;
  }
  return -1;
}

kernel void vm_tv_forward(global const float* grid, global float* partial, int rows, int rx, int ry, int rz, int r0,
                          int r1, int r2) {
  const int row = get_global_id(0);
  if (row >= rows) return;
  const VMLayout L = vm_layout(rx, ry, rz, r0, r1, r2);
  int v;
  const int m = row_mode(&L, row, &v);
  const int nu = L.res[mode_u(m)], nv = L.res[mode_v(m)], R = L.rank[m];
  const global float* P = grid + L.plane_off[m] + v * nu * R;
  float su = 0.0f, sv = 0.0f;
  for (int k = 0; k < nu * R; ++k) {
    if (k + R < nu * R) {
      const float d = P[k + R] - P[k];
      su += d * d;
    }
    if (v + 1 < nv) {
      const float d = P[k + nu * R] - P[k];
      sv += d * d;
    }
  }
  partial[row] = su / (float)(R * nv * (nu - 1)) + sv / (float)(R * (nv - 1) * nu);
}

// dgrid += weight * d(TV)/d(plane), one work-item per plane element.
kernel void vm_tv_backward(global const float* grid, global float* dgrid, float weight, int rx, int ry, int rz, int r0,
                           int r1, int r2) {
  const int k = get_global_id(0);
  const VMLayout L = vm_layout(rx, ry, rz, r0, r1, r2);
  if (k >= L.line_off[0]) return;
  const int m = k < L.plane_off[1] ? 0 : (k < L.plane_off[2] ? 1 : 2);
  const int nu = L.res[mode_u(m)], nv = L.res[mode_v(m)], R = L.rank[m];
  const int e = k - L.plane_off[m];
  const int v = e / (nu * R), u = (e / R) % nu;
  const float cu = 2.0f / (float)(R * nv * (nu - 1)), cv = 2.0f / (float)(R * (nv - 1) * nu);
  const float x = grid[k];
  float g = 0.0f;
  if (u > 0) g += cu * (x - grid[k - R]);
  if (u + 1 < nu) g -= cu * (grid[k + R] - x);
  if (v > 0) g += cv * (x - grid[k - nu * R]);
  if (v + 1 < nv) g -= cv * (grid[k + nu * R] - x);
  dgrid[k] += weight * g;
}

// L1: sum over the 6 parts of mean |x| (TensoRF's density L1). part_of gives the part and its size.
inline int part_of(const VMLayout* L, int k, int* size) {
  const int starts[7] = {L->plane_off[0], L->plane_off[1], L->plane_off[2], L->line_off[0],
                         L->line_off[1],  L->line_off[2],  L->numel};
  for (int q = 0; q < 6; ++q)
    if (k < starts[q + 1]) {
      *size = starts[q + 1] - starts[q];
      return q;
    }
  *size = 1;
  return -1;
}

// Forward: work-item b sums |x| / size(part) over elements [b*block, (b+1)*block).
kernel void vm_l1_forward(global const float* grid, global float* partial, int blocks, int block, int rx, int ry,
                          int rz, int r0, int r1, int r2) {
  const int b = get_global_id(0);
  if (b >= blocks) return;
  const VMLayout L = vm_layout(rx, ry, rz, r0, r1, r2);
  float s = 0.0f;
  const int end = min(L.numel, (b + 1) * block);
  for (int k = b * block; k < end; ++k) {
    int size;
    part_of(&L, k, &size);
    s += fabs(grid[k]) / (float)size;
  }
  partial[b] = s;
}

// dgrid += weight * sign(x) / size(part); sign(0) = 0.
kernel void vm_l1_backward(global const float* grid, global float* dgrid, float weight, int rx, int ry, int rz, int r0,
                           int r1, int r2) {
  const int k = get_global_id(0);
  const VMLayout L = vm_layout(rx, ry, rz, r0, r1, r2);
  if (k >= L.numel) return;
  int size;
  part_of(&L, k, &size);
  const float x = grid[k];
  const float s = x > 0.0f ? 1.0f : (x < 0.0f ? -1.0f : 0.0f);
  dgrid[k] += weight * s / (float)size;
}

// ---- resampling to a new resolution (and optionally a sub-box) ----------------------------------------
// New grid cell (one work-item per plane cell or line cell of the new layout, all ranks): its position in the
// new grid's normalised coordinates, mapped into the old grid's [lo, hi] box (default [-1,1]^3: plain
// upsampling), bilinear/linear resampling with align_corners=True.
inline float new_to_old(int i, int n_new, float lo, float hi) {
  const float q = (float)i / (float)(n_new - 1);  // [0,1]
  return clamp(lo + (hi - lo) * q, -1.0f, 1.0f);
}

kernel void vm_resample(global const float* old_grid, global float* new_grid, int ncells, int ox, int oy, int oz,
                        int nx, int ny, int nz, int r0, int r1, int r2, float lox, float loy, float loz, float hix,
                        float hiy, float hiz) {
  int c = get_global_id(0);
  if (c >= ncells) return;
  const VMLayout O = vm_layout(ox, oy, oz, r0, r1, r2);
  const VMLayout N = vm_layout(nx, ny, nz, r0, r1, r2);
  const float lo[3] = {lox, loy, loz}, hi[3] = {hix, hiy, hiz};
  // Planes first (3 parts), then lines (3 parts), cells counted without the rank.
  for (int m = 0; m < 3; ++m) {
    const int u = mode_u(m), v = mode_v(m);
    const int cells = N.res[u] * N.res[v];
    if (c < cells) {
      const int iu = c % N.res[u], iv = c / N.res[u];
      float3 p = (float3)(0.0f);
      float pu = new_to_old(iu, N.res[u], lo[u], hi[u]), pv = new_to_old(iv, N.res[v], lo[v], hi[v]);
      p = u == 0 ? (float3)(pu, v == 1 ? pv : 0.0f, v == 2 ? pv : 0.0f) : (float3)(0.0f, pu, pv);
      const ModeTaps T = mode_taps(&O, m, p);
      global float* dst = new_grid + N.plane_off[m] + c * T.R;
      for (int r = 0; r < T.R; ++r) dst[r] = plane1(old_grid, &T, r);
      return;
    }
    c -= cells;
  }
  for (int m = 0; m < 3; ++m) {
    const int w = mode_w(m);
    const int cells = N.res[w];
    if (c < cells) {
      const float pw = new_to_old(c, N.res[w], lo[w], hi[w]);
      const float3 p = w == 0 ? (float3)(pw, 0.0f, 0.0f) : (w == 1 ? (float3)(0.0f, pw, 0.0f) : (float3)(0.0f, 0.0f, pw));
      const ModeTaps T = mode_taps(&O, m, p);
      global float* dst = new_grid + N.line_off[m] + c * T.R;
      for (int r = 0; r < T.R; ++r) dst[r] = line1(old_grid, &T, r);
      return;
    }
    c -= cells;
  }
}

// ---- alpha mask ------------------------------------------------------------------------------------
// Occupancy at voxel centres of an [mz][my][mx] grid over the box: alpha = 1 - exp(-sigma * step) > thr.
kernel void alpha_mask_eval(global const float* grid, global uchar* mask, int mx, int my, int mz, int rx, int ry,
                            int rz, int r0, int r1, int r2, int act, float step, float thr) {
  const int i = get_global_id(0);
  if (i >= mx * my * mz) return;
  const int x = i % mx, y = (i / mx) % my, z = i / (mx * my);
  const float3 p = (float3)(-1.0f + (2.0f * x + 1.0f) / (float)mx, -1.0f + (2.0f * y + 1.0f) / (float)my,
                            -1.0f + (2.0f * z + 1.0f) / (float)mz);
  const VMLayout L = vm_layout(rx, ry, rz, r0, r1, r2);
  const float sigma = density_act(density_at(grid, &L, p), act);
  const float alpha = -expm1(-sigma * step);
  mask[i] = alpha > thr ? 1 : 0;
}

// 3x3x3 dilation (TensoRF max-pools its alpha volume the same way): a voxel next to an occupied one is
// kept, so thin surfaces between voxel centres are not skipped.
kernel void alpha_mask_dilate(global const uchar* src, global uchar* dst, int mx, int my, int mz) {
  const int i = get_global_id(0);
  if (i >= mx * my * mz) return;
  const int x = i % mx, y = (i / mx) % my, z = i / (mx * my);
  uchar o = 0;
  for (int dz = -1; dz <= 1 && !o; ++dz)
    for (int dy = -1; dy <= 1 && !o; ++dy)
      for (int dx = -1; dx <= 1 && !o; ++dx) {
        const int xx = x + dx, yy = y + dy, zz = z + dz;
        if (xx < 0 || yy < 0 || zz < 0 || xx >= mx || yy >= my || zz >= mz) continue;
        o = src[(zz * my + yy) * mx + xx];
      }
  dst[i] = o;
}

// ---- appearance head: fused bias + activation ------------------------------------------------------------
// z [n, C] in place: relu(z + b) (act 0) or sigmoid(z + b) (act 1).
kernel void bias_act_forward(global float* z, global const float* b, int n, int C, int act) {
  const int i = get_global_id(0);
  if (i >= n * C) return;
  const float x = z[i] + b[i % C];
  z[i] = act == 0 ? fmax(x, 0.0f) : 1.0f / (1.0f + exp(-x));
}

// dy [n, C] in place -> d(pre-activation), from the activation's output y.
kernel void bias_act_backward(global float* dy, global const float* y, int n, int C, int act) {
  const int i = get_global_id(0);
  if (i >= n * C) return;
  const float yv = y[i];
  dy[i] = act == 0 ? (yv > 0.0f ? dy[i] : 0.0f) : dy[i] * yv * (1.0f - yv);
}

// Head input with view dependence: out [n, D] = [h (27), d (3), sin(2^k d), cos(2^k d) for k < npe].
kernel void head_concat_view(global const float* h, global const float* dirs, global float* out, int n, int H,
                             int npe) {
  const int i = get_global_id(0);
  if (i >= n) return;
  const int D = H + 3 + 6 * npe;
  global float* o = out + (long)i * D;
  for (int k = 0; k < H; ++k) o[k] = h[(long)i * H + k];
  const float3 d = vload3(i, dirs);
  o[H] = d.x; o[H + 1] = d.y; o[H + 2] = d.z;
  for (int k = 0; k < npe; ++k) {
    const float s = (float)(1 << k);
    float3 sd = sin(d * s), cd = cos(d * s);
    const int b = H + 3 + 6 * k;
    o[b] = sd.x; o[b + 1] = sd.y; o[b + 2] = sd.z;
    o[b + 3] = cd.x; o[b + 4] = cd.y; o[b + 5] = cd.z;
  }
}
