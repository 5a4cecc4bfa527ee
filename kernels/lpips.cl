// LPIPS per-position distance of one tap (lib/eval/lpips_map.cpp):
//
//   d[p] = sum_c w[c] * (u[c,p] - v[c,p])^2,   u = a / (||a[.,p]|| + eps),  v likewise from b,
//
// a, b: [C, HW] features of the two images, w: [C] the tap's linear head, ||.|| over channels.
// Each work-item takes 8 neighbouring positions as one float8 (the "one work-item per position" loop,
// vectorised by hand as the other kernels here are: PoCL does not vectorise these channel loops itself)
// and loops over channels with stride HW; float accumulation. Global: (ceil(HW / 8)).
//
// Magnitudes: sum x^2 overflows float once features reach ~1e18 (C = 512). The plain sum is used when it
// is finite; otherwise (rare: checked per group of 8) it is recomputed as sum (x/m)^2 with m = max |x|,
// and the norm is m * sqrt(that). u = (x * f1) * f2 with f1 = 1/m (1 for the plain sum) and
// f2 = 1 / (sqrt(..) + eps * f1), which is x / (||x|| + eps) without overflow. Squares of features below
// ~1e-19 underflow, but their norm is then < 1e-7 eps and does not change ||x|| + eps in float. An
// all-zero position gives u = 0 (the eps), as the reference.

// Identical features must give exactly 0 (LPIPS(a, a) == 0): without this the compiler may fuse
// u - v into fma(a, f, -v), which rounds u and v differently.
#pragma OPENCL FP_CONTRACT OFF

#define LPIPS_EPS 1e-10f

// 8 positions from p0 (zeros past the end of the map).
inline float8 load_positions(__global const float* x, int p0, int HW) {
  if (p0 + 8 <= HW) return vload8(0, x + p0);
  float t[8];
  for (int j = 0; j < 8; ++j) t[j] = p0 + j < HW ? x[p0 + j] : 0.0f;
  return vload8(0, t);
}

inline void store_positions(__global float* y, int p0, int HW, float8 v) {
  if (p0 + 8 <= HW) {
    vstore8(v, 0, y + p0);
    return;
  }
  float t[8];
  vstore8(v, 0, t);
  for (int j = 0; j < 8; ++j)
    if (p0 + j < HW) y[p0 + j] = t[j];
}

// The factors f1, f2 of u = (x * f1) * f2 (above), and 1/sqrt(..) for the unit vector x^ = x * f1 * that.
typedef struct {
  float8 f1, f2, inv_sq;
} NormFactors;

inline NormFactors norm_factors(__global const float* x, int p0, int C, int HW) {
  float8 s = (float8)(0.0f), m = (float8)(0.0f);
  for (int c = 0; c < C; ++c) {
    const float8 v = load_positions(x + (long)c * HW, p0, HW);
    s += v * v;
    m = fmax(m, fabs(v));
  }
  float8 f1 = (float8)(1.0f);
  const int8 over = isinf(s);
  if (any(over)) {  // rescale the lanes whose plain sum overflowed (m > 0 there)
    const float8 ms = select((float8)(1.0f), m, over);
    float8 t = (float8)(0.0f);
    for (int c = 0; c < C; ++c) {
      const float8 r = load_positions(x + (long)c * HW, p0, HW) / ms;
      t += r * r;
    }
    s = select(s, t, over);
    f1 = select(f1, (float8)(1.0f) / ms, over);
  }
  const float8 sq = sqrt(s);
  NormFactors f;
  f.f1 = f1;
  f.f2 = (float8)(1.0f) / (sq + LPIPS_EPS * f1);
  f.inv_sq = select((float8)(0.0f), (float8)(1.0f) / sq, sq > 0.0f);
  return f;
}

__kernel void lpips_distance_forward(__global const float* a, __global const float* b, __global const float* w,
                                     __global float* d, int C, int HW) {
  const int p0 = get_global_id(0) * 8;
  if (p0 >= HW) return;
  const NormFactors fa = norm_factors(a, p0, C, HW);
  const NormFactors fb = norm_factors(b, p0, C, HW);
  float8 acc = (float8)(0.0f);
  for (int c = 0; c < C; ++c) {
    const long off = (long)c * HW;
    const float8 u = (load_positions(a + off, p0, HW) * fa.f1) * fa.f2;
    const float8 v = (load_positions(b + off, p0, HW) * fb.f1) * fb.f2;
    const float8 diff = u - v;
    acc += w[c] * (diff * diff);
  }
  store_positions(d, p0, HW, acc);
}

// d a given dd [HW]. With r_c = 2 dd w_c (u_c - v_c), D = ||a|| + eps and a^ = a / ||a||:
//   da_k = (r_k - a^_k * sum_c r_c u_c) / D.
// At an all-zero position u = a / eps near 0 in every direction, so da = r / eps (a^ taken as 0).
__kernel void lpips_distance_backward(__global const float* a, __global const float* b, __global const float* w,
                                      __global const float* dd, __global float* da, int C, int HW) {
  const int p0 = get_global_id(0) * 8;
  if (p0 >= HW) return;
  const NormFactors fa = norm_factors(a, p0, C, HW);
  const NormFactors fb = norm_factors(b, p0, C, HW);
  const float8 g2 = 2.0f * load_positions(dd, p0, HW);
  float8 dot = (float8)(0.0f);  // sum_c r_c u_c
  for (int c = 0; c < C; ++c) {
    const long off = (long)c * HW;
    const float8 u = (load_positions(a + off, p0, HW) * fa.f1) * fa.f2;
    const float8 v = (load_positions(b + off, p0, HW) * fb.f1) * fb.f2;
    dot += (g2 * w[c] * (u - v)) * u;
  }
  for (int c = 0; c < C; ++c) {
    const long off = (long)c * HW;
    const float8 x = load_positions(a + off, p0, HW) * fa.f1;
    const float8 u = x * fa.f2;
    const float8 v = (load_positions(b + off, p0, HW) * fb.f1) * fb.f2;
    const float8 r = g2 * w[c] * (u - v);
    const float8 hat = x * fa.inv_sq;
    store_positions(da + off, p0, HW, ((r - hat * dot) * fa.f1) * fa.f2);
  }
}
