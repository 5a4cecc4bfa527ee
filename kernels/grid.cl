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

// Everything on the per-point path is forced inline: PoCL otherwise keeps mode_taps/density_at as calls,
// and only after inlining do the mode index (0,1,2 literal at each call) and the rank (RANK0..2) become
// constants, so the axis choice folds away and the rank loops unroll into straight vector loads.
#define ALWAYS_INLINE inline __attribute__((always_inline))

#ifdef RANK0
#define RANK_OF(L, m) ((m) == 0 ? RANK0 : ((m) == 1 ? RANK1 : RANK2))
#else
#define RANK_OF(L, m) ((L)->rank[m])
#endif

// Lower tap index and fraction along each axis at point p: computed once per point and shared by the
// three modes (each axis is used by all three: twice as a plane axis, once as a line axis).
typedef struct {
  int i[3];
  float f[3];
} PointCell;

// Align-corners coordinate -> lower tap index in [0, n-2] and fraction in [0,1] (p = +1 gives n-2, 1),
// the three axes at once. Only for p inside [-1,1]^3 (callers check inside_box or clamp): then f >= 0 and
// truncation is floor (PoCL's floor() is a dozen branchy instructions per call).
// This and cell_taps fill an out-parameter rather than return the struct: a struct return is an sret
// pointer, which clang marks noalias, and inlining it leaves llvm.experimental.noalias.scope.decl calls
// that Oclgrind's interpreter cannot run (scripts/oclgrind.sh); once inlined, the code is the same.
ALWAYS_INLINE void point_cell(const VMLayout* L, float3 p, PointCell* c) {
  const int4 n = (int4)(L->res[0], L->res[1], L->res[2], 2);
  const float4 f = ((float4)(p, -1.0f) + 1.0f) * 0.5f * convert_float4(n - 1);
  const int4 i = min(convert_int4(f), n - 2);
  const float4 fr = clamp(f - convert_float4(i), 0.0f, 1.0f);
  c->i[0] = i.x; c->i[1] = i.y; c->i[2] = i.z;
  c->f[0] = fr.x; c->f[1] = fr.y; c->f[2] = fr.z;
}

// Taps of one mode: 4 plane taps and 2 line taps (element offsets of rank 0) and their weights.
typedef struct {
  int pt[4];
  float pw[4];
  int lt[2];
  float lw[2];
  int R;
} ModeTaps;

ALWAYS_INLINE void cell_taps(const VMLayout* L, const PointCell* c, int m, ModeTaps* T) {
  const int u = mode_u(m), v = mode_v(m), w = mode_w(m);
  const int nu = L->res[u], R = RANK_OF(L, m);
  const float fu = c->f[u], fv = c->f[v], fw = c->f[w];
  const int base = L->plane_off[m] + (c->i[v] * nu + c->i[u]) * R;
  T->pt[0] = base;               T->pw[0] = (1.0f - fu) * (1.0f - fv);
  T->pt[1] = base + R;           T->pw[1] = fu * (1.0f - fv);
  T->pt[2] = base + nu * R;      T->pw[2] = (1.0f - fu) * fv;
  T->pt[3] = base + nu * R + R;  T->pw[3] = fu * fv;
  T->lt[0] = L->line_off[m] + c->i[w] * R; T->lw[0] = 1.0f - fw;
  T->lt[1] = T->lt[0] + R;                 T->lw[1] = fw;
  T->R = R;
}

// Taps of mode m at point p (resampling evaluates one mode at a time).
inline void mode_taps(const VMLayout* L, int m, float3 p, ModeTaps* T) {
  PointCell c;
  point_cell(L, p, &c);
  cell_taps(L, &c, m, T);
}

// Bilinear plane value and linear line value for ranks [r, r+W) (W = 8, 4: plane8, line8, plane4, line4)
// and for rank r alone (plane1, line1).
#define PLANE_AND_LINE_OF_WIDTH(W)                                                                     \
  ALWAYS_INLINE float##W plane##W(const global float* g, const ModeTaps* T, int r) {                  \
    float##W a = T->pw[0] * vload##W(0, g + T->pt[0] + r);                                            \
    a = fma((float##W)(T->pw[1]), vload##W(0, g + T->pt[1] + r), a);                                  \
    a = fma((float##W)(T->pw[2]), vload##W(0, g + T->pt[2] + r), a);                                  \
    return fma((float##W)(T->pw[3]), vload##W(0, g + T->pt[3] + r), a);                               \
  }                                                                                                    \
  ALWAYS_INLINE float##W line##W(const global float* g, const ModeTaps* T, int r) {                   \
    return fma((float##W)(T->lw[1]), vload##W(0, g + T->lt[1] + r), T->lw[0] * vload##W(0, g + T->lt[0] + r)); \
  }
PLANE_AND_LINE_OF_WIDTH(8)
PLANE_AND_LINE_OF_WIDTH(4)
ALWAYS_INLINE float plane1(const global float* g, const ModeTaps* T, int r) {
  return T->pw[0] * g[T->pt[0] + r] + T->pw[1] * g[T->pt[1] + r] + T->pw[2] * g[T->pt[2] + r] +
         T->pw[3] * g[T->pt[3] + r];
}
ALWAYS_INLINE float line1(const global float* g, const ModeTaps* T, int r) {
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

// sum_r plane_m[r] * line_m[r]: 8 ranks at a time (one AVX register), then 4, then a scalar tail; with a
// compile-time rank the dead steps vanish.
ALWAYS_INLINE float mode_dot(const global float* g, const ModeTaps* T) {
  const int R = T->R;
  int r = 0;
  float8 s8 = (float8)(0.0f);
  for (; r + 8 <= R; r += 8) s8 = fma(plane8(g, T, r), line8(g, T, r), s8);
  float4 s4 = s8.lo + s8.hi;
  for (; r + 4 <= R; r += 4) s4 = fma(plane4(g, T, r), line4(g, T, r), s4);
  float s = (s4.x + s4.y) + (s4.z + s4.w);
  for (; r < R; ++r) s = fma(plane1(g, T, r), line1(g, T, r), s);
  return s;
}

ALWAYS_INLINE float density_at(const global float* g, const VMLayout* L, float3 p) {
  PointCell c;
  point_cell(L, p, &c);
  ModeTaps T0, T1, T2;
  cell_taps(L, &c, 0, &T0);
  cell_taps(L, &c, 1, &T1);
  cell_taps(L, &c, 2, &T2);
  return mode_dot(g, &T0) + mode_dot(g, &T1) + mode_dot(g, &T2);
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

// Mode m's features plane_m[r] * line_m[r] into o[0, R).
ALWAYS_INLINE void mode_features(const global float* g, const ModeTaps* T, global float* o) {
  const int R = T->R;
  int r = 0;
  for (; r + 8 <= R; r += 8) vstore8(plane8(g, T, r) * line8(g, T, r), 0, o + r);
  for (; r + 4 <= R; r += 4) vstore4(plane4(g, T, r) * line4(g, T, r), 0, o + r);
  for (; r < R; ++r) o[r] = plane1(g, T, r) * line1(g, T, r);
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
  PointCell c;
  point_cell(&L, p, &c);
  ModeTaps T0, T1, T2;
  cell_taps(&L, &c, 0, &T0);
  cell_taps(&L, &c, 1, &T1);
  cell_taps(&L, &c, 2, &T2);
  mode_features(grid, &T0, out + L.feat_off[0]);
  mode_features(grid, &T1, out + L.feat_off[1]);
  mode_features(grid, &T2, out + L.feat_off[2]);
}

// ---- sampling backward (scatter) --------------------------------------------------------------------------
// d(plane_m[r] line_m[r]) = line_m[r] d(plane) + plane_m[r] d(line): tap k of the plane receives
// g_r * line_m[r] * pw[k], tap k of the line g_r * plane_m[r] * lw[k]. Taps of zero weight are skipped
// (they change nothing, and skipping keeps a non-finite neighbour from spreading NaN). Devices with many
// compute units take the fixed-point scatter of grid_fixed.cl instead.

// dst[0..n) += a * w for n = 8, 4, 1 (one tap of one rank chunk). The 8-wide add is two 4-wide
// read-modify-writes on purpose: LLVM splits an unaligned 32-byte store into two 16-byte halves, and the
// next point's 32-byte load of the same tap (neighbouring samples share cells) then cannot be forwarded
// from the store buffer and stalls; 16-byte stores and loads pair up.
ALWAYS_INLINE void add8(global float* d, float8 a, float w) {
  vstore4(fma(a.lo, (float4)(w), vload4(0, d)), 0, d);
  vstore4(fma(a.hi, (float4)(w), vload4(1, d)), 1, d);
}
ALWAYS_INLINE void add4(global float* d, float4 a, float w) { vstore4(fma(a, (float4)(w), vload4(0, d)), 0, d); }
ALWAYS_INLINE void add1(global float* d, float a, float w) { *d = fma(a, w, *d); }

// One rank chunk [r, r+W) of one mode: the 4 plane taps get gp * pw[k], the 2 line taps gl * lw[k].
// Written out tap by tap (no loop over a tap array, which PoCL keeps in memory).
#define SCATTER_CHUNK(ADD, T, dst, r, gp, gl)                         \
  do {                                                                \
    if ((T)->pw[0] != 0.0f) ADD((dst) + (T)->pt[0] + (r), gp, (T)->pw[0]); \
    if ((T)->pw[1] != 0.0f) ADD((dst) + (T)->pt[1] + (r), gp, (T)->pw[1]); \
    if ((T)->pw[2] != 0.0f) ADD((dst) + (T)->pt[2] + (r), gp, (T)->pw[2]); \
    if ((T)->pw[3] != 0.0f) ADD((dst) + (T)->pt[3] + (r), gp, (T)->pw[3]); \
    if ((T)->lw[0] != 0.0f) ADD((dst) + (T)->lt[0] + (r), gl, (T)->lw[0]); \
    if ((T)->lw[1] != 0.0f) ADD((dst) + (T)->lt[1] + (r), gl, (T)->lw[1]); \
  } while (0)

// Plain-add scatter of one mode into a private gradient copy, 8/4/1 ranks at a time. gf points at the
// mode's d(feature) values when per_rank (features), else g0 is the one gradient of every rank (density).
// dst must not alias grid (the kernels declare both restrict), so the grid loads need not wait for the
// stores of the previous chunk.
ALWAYS_INLINE void scatter_mode_private(const global float* restrict grid, global float* restrict dst,
                                        const ModeTaps* T, const global float* gf, float g0, int per_rank) {
  const int R = T->R;
  int r = 0;
  for (; r + 8 <= R; r += 8) {
    const float8 g = per_rank ? vload8(0, gf + r) : (float8)(g0);
    if (per_rank && !any(g != 0.0f)) continue;
    const float8 gp = g * line8(grid, T, r), gl = g * plane8(grid, T, r);
    SCATTER_CHUNK(add8, T, dst, r, gp, gl);
  }
  for (; r + 4 <= R; r += 4) {
    const float4 g = per_rank ? vload4(0, gf + r) : (float4)(g0);
    if (per_rank && !any(g != 0.0f)) continue;
    const float4 gp = g * line4(grid, T, r), gl = g * plane4(grid, T, r);
    SCATTER_CHUNK(add4, T, dst, r, gp, gl);
  }
  for (; r < R; ++r) {
    const float g = per_rank ? gf[r] : g0;
    if (g == 0.0f) continue;
    const float gp = g * line1(grid, T, r), gl = g * plane1(grid, T, r);
    SCATTER_CHUNK(add1, T, dst, r, gp, gl);
  }
}

// Scatters point i's gradient into dst. mode 0: density, g = dsig[i] * act'(sigma[i]) for every rank;
// mode 1: features, row i of dfeat [n, nfeat] (passed as dsig). per_rank is a literal at the call sites,
// so each case compiles to its own straight-line code.
ALWAYS_INLINE void scatter_point(const global float* restrict grid, global float* restrict dst, const VMLayout* L,
                                 float3 p, int i,
                                 const global float* dsig, const global float* sigma, int act, int per_rank) {
  float g0 = 0.0f;
  const global float* gf = dsig;
  if (per_rank) {
    gf = dsig + (long)i * L->nfeat;
  } else {
    g0 = dsig[i] * density_act_grad(sigma[i], act);
    if (g0 == 0.0f) return;
  }
  PointCell c;
  point_cell(L, p, &c);
  // The modes written out (not a loop) so that each call sees a literal mode index and rank.
  ModeTaps T0, T1, T2;
  cell_taps(L, &c, 0, &T0);
  cell_taps(L, &c, 1, &T1);
  cell_taps(L, &c, 2, &T2);
  scatter_mode_private(grid, dst, &T0, gf + L->feat_off[0], g0, per_rank);
  scatter_mode_private(grid, dst, &T1, gf + L->feat_off[1], g0, per_rank);
  scatter_mode_private(grid, dst, &T2, gf + L->feat_off[2], g0, per_rank);
}

// Deterministic privatised scatter: work-item c (of `copies`) handles points [c*chunk, (c+1)*chunk) in
// order with plain adds into its own copy: copy 0 is dgrid itself (accumulates), copies 1.. live in
// scratch ((copies-1) * numel floats, zeroed here) and are summed into dgrid by vm_reduce_copies.
kernel void vm_scatter_private(global const float* pts, global const float* restrict grid, global const float* dsig,
                               global const float* sigma, global float* restrict dgrid, global float* restrict scratch,
                               int n, int chunk,
                               int rx, int ry, int rz, int r0, int r1, int r2, int mode, int act) {
  const int c = get_global_id(0);
  const VMLayout L = vm_layout(rx, ry, rz, r0, r1, r2);
  global float* dst = c == 0 ? dgrid : scratch + (long)(c - 1) * L.numel;
  if (c > 0) {
    int k = 0;
    for (; k + 8 <= L.numel; k += 8) vstore8((float8)(0.0f), 0, dst + k);
    for (; k < L.numel; ++k) dst[k] = 0.0f;
  }
  const int begin = c * chunk, end = min(n, begin + chunk);
  if (mode == 0) {
    for (int i = begin; i < end; ++i) {
      const float3 p = vload3(i, pts);
      if (inside_box(p)) scatter_point(grid, dst, &L, p, i, dsig, sigma, act, 0);
    }
  } else {
    for (int i = begin; i < end; ++i) {
      const float3 p = vload3(i, pts);
      if (inside_box(p)) scatter_point(grid, dst, &L, p, i, dsig, sigma, act, 1);
    }
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
// Plane m's gradient, one work-item per element: global (nu * R, nv) over the plane [nv][nu][R] at element
// offset off. The u neighbours are R elements away and the v neighbours nu * R, so the borders are
// comparisons of the flat index: no integer division per element (which the 1D version spent most of its
// time on). cu, cv: TensoRF's 2 / count normalisers of the u and v differences.
kernel void vm_tv_backward(global const float* grid, global float* dgrid, float weight, int off, int nu, int nv,
                           int R, float cu, float cv) {
  const int i = get_global_id(0), v = get_global_id(1);
  const int row = nu * R;
  if (i >= row || v >= nv) return;
  const long k = off + (long)v * row + i;
  const float x = grid[k];
  float g = 0.0f;
  if (i >= R) g += cu * (x - grid[k - R]);
  if (i + R < row) g -= cu * (grid[k + R] - x);
  if (v > 0) g += cv * (x - grid[k - row]);
  if (v + 1 < nv) g -= cv * (grid[k + row] - x);
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

// The ranks of one new cell, dst[0, R): mode m's plane (or line) values at p in the old grid.
inline void resample_cell(const VMLayout* O, int m, float3 p, const global float* old_grid, global float* dst,
                          bool plane) {
  ModeTaps T;
  mode_taps(O, m, p, &T);
  for (int r = 0; r < T.R; ++r) dst[r] = plane ? plane1(old_grid, &T, r) : line1(old_grid, &T, r);
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
      resample_cell(&O, m, p, old_grid, new_grid + N.plane_off[m] + c * RANK_OF(&O, m), true);
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
      resample_cell(&O, m, p, old_grid, new_grid + N.line_off[m] + c * RANK_OF(&O, m), false);
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
