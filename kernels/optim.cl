// Adam, one fused pass over param, grad and both moments; one work-item per SPAN elements in float4
// steps, the last work-item finishing a tail of n % 4 elements one by one.
//
// Bias correction folded into two host-computed scalars (double precision there):
//   lr_t = lr / (1 - beta1^t),  inv_sqrt_bc2 = 1 / sqrt(1 - beta2^t), so
//   p -= lr * mhat / (sqrt(vhat) + eps)  ==  p -= lr_t * m / (sqrt(v) * inv_sqrt_bc2 + eps).

#define SPAN 64

__kernel void adam_step(__global float* p, __global const float* g, __global float* m, __global float* v, int n,
                        float beta1, float beta2, float lr_t, float inv_sqrt_bc2, float eps) {
  int j = get_global_id(0) * SPAN;
  if (j >= n) return;
  const int end = min(j + SPAN, n);
  for (; j + 4 <= end; j += 4) {
    const float4 gg = vload4(0, g + j);
    const float4 mm = fma(beta1, vload4(0, m + j), (1.0f - beta1) * gg);
    const float4 vv = fma(beta2, vload4(0, v + j), (1.0f - beta2) * gg * gg);
    vstore4(mm, 0, m + j);
    vstore4(vv, 0, v + j);
    vstore4(vload4(0, p + j) - lr_t * mm / fma(sqrt(vv), inv_sqrt_bc2, eps), 0, p + j);
  }
  for (; j < end; ++j) {
    const float gg = g[j];
    const float mm = fma(beta1, m[j], (1.0f - beta1) * gg);
    const float vv = fma(beta2, v[j], (1.0f - beta2) * gg * gg);
    m[j] = mm;
    v[j] = vv;
    p[j] -= lr_t * mm / fma(sqrt(vv), inv_sqrt_bc2, eps);
  }
}
