// LPIPS per-position distance of one tap (lib/eval/lpips_map.cpp):
//
//   d[p] = sum_c w[c] * (u[c,p] - v[c,p])^2,   u = a / (||a[.,p]|| + eps),  v likewise from b,
//
// a, b: [C, HW] features of the two images, w: [C] the tap's linear head, ||.|| over channels.
// One work-item per position p, looping over channels with stride HW (neighbouring work-items read
// neighbouring floats); float accumulation.
//
// Features reach 1e18 and more in principle (and x^2 overflows float beyond 1.8e19): the norm is taken as
// m * sqrt(sum (x/m)^2) with m = max_c |x|, accumulated in one pass with the scale m raised as larger
// values appear, so no square exceeds 1. The unit vector then is (x * f1) * f2, two factors that stay
// finite for every m (see norm_factors). An all-zero position gives u = 0 (the eps), as the reference.

// Identical features must give exactly 0 (LPIPS(a, a) == 0): without this the compiler may fuse
// u - v into fma(a, f, -v), which rounds u and v differently.
#pragma OPENCL FP_CONTRACT OFF

#define LPIPS_EPS 1e-10f
// Below this, ||x|| <= 23 * m is < 1e-18 of eps: ||x|| + eps == eps in float, and 1/m may overflow.
#define LPIPS_TINY 1e-30f

// Max |x| over channels and sqrt(sum (x/m)^2) (0 and 0 for an all-zero position).
inline float2 scaled_norm(__global const float* x, int C, int HW) {
  float m = 0.0f, s = 0.0f;
  for (int c = 0; c < C; ++c) {
    const float ax = fabs(x[(long)c * HW]);
    if (ax > m) {
      const float r = m / ax;
      s = s * r * r + 1.0f;
      m = ax;
    } else if (ax > 0.0f) {
      const float r = ax / m;
      s += r * r;
    }
  }
  return (float2)(m, sqrt(s));
}

// u_c = (x_c * f.x) * f.y equals x_c / (m * sq + eps) without overflow or a denormal reciprocal.
inline float2 norm_factors(float2 ms) {
  const float m = ms.x, sq = ms.y;
  if (m < LPIPS_TINY) return (float2)(1.0f, 1.0f / (m * sq + LPIPS_EPS));
  const float inv_m = 1.0f / m;
  return (float2)(inv_m, 1.0f / (sq + LPIPS_EPS * inv_m));
}

// Global: (HW).
__kernel void lpips_distance_forward(__global const float* a, __global const float* b, __global const float* w,
                                     __global float* d, int C, int HW) {
  const int p = get_global_id(0);
  if (p >= HW) return;
  const float2 fa = norm_factors(scaled_norm(a + p, C, HW));
  const float2 fb = norm_factors(scaled_norm(b + p, C, HW));
  float acc = 0.0f;
  for (int c = 0; c < C; ++c) {
    const long i = (long)c * HW + p;
    const float diff = (a[i] * fa.x) * fa.y - (b[i] * fb.x) * fb.y;
    acc += w[c] * diff * diff;
  }
  d[p] = acc;
}

// d a given dd [HW]. With r_c = 2 dd w_c (u_c - v_c), D = ||a|| + eps and a^ = a / ||a||:
//   da_k = (r_k - a^_k * sum_c r_c u_c) / D.
// At an all-zero position u = a / eps near 0 in every direction, so da = r / eps (a^ taken as 0).
// Global: (HW).
__kernel void lpips_distance_backward(__global const float* a, __global const float* b, __global const float* w,
                                      __global const float* dd, __global float* da, int C, int HW) {
  const int p = get_global_id(0);
  if (p >= HW) return;
  const float2 ms = scaled_norm(a + p, C, HW);
  const float2 fa = norm_factors(ms);
  const float2 fb = norm_factors(scaled_norm(b + p, C, HW));
  const float g2 = 2.0f * dd[p];
  float dot = 0.0f;  // sum_c r_c u_c
  for (int c = 0; c < C; ++c) {
    const long i = (long)c * HW + p;
    const float u = (a[i] * fa.x) * fa.y;
    dot += g2 * w[c] * (u - (b[i] * fb.x) * fb.y) * u;
  }
  // a^_k = (a_k / m) / sq, by a reciprocal unless 1/m could overflow; 0 for an all-zero position.
  const float m = ms.x;
  const float inv_m = m >= LPIPS_TINY ? 1.0f / m : 0.0f;
  const float inv_sq = ms.y > 0.0f ? 1.0f / ms.y : 0.0f;
  for (int c = 0; c < C; ++c) {
    const long i = (long)c * HW + p;
    const float u = (a[i] * fa.x) * fa.y;
    const float r = g2 * w[c] * (u - (b[i] * fb.x) * fb.y);
    const float hat = m >= LPIPS_TINY ? (a[i] * inv_m) * inv_sq : m > 0.0f ? (a[i] / m) * inv_sq : 0.0f;
    da[i] = ((r - hat * dot) * fa.x) * fa.y;
  }
}
