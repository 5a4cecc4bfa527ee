// Split-K GEMM, second stage (host/gemm.cpp): C = alpha * sum_p partial[p] + beta * C over the chunks of
// K that CLBlast multiplied into partial [parts, M, N]. The chunks are added in order, so the result does
// not depend on scheduling. beta = 0 does not read C (BLAS semantics: NaN there must not leak).
// Global: (N, M).
__kernel void gemm_sum_chunks(__global const float* partial, int parts, int M, int N, float alpha, float beta,
                              __global float* C, int c_off, int ldc) {
  const int j = get_global_id(0), i = get_global_id(1);
  if (j >= N || i >= M) return;
  const long mn = (long)M * N, o = (long)i * N + j;
  float s = 0.0f;
  for (int p = 0; p < parts; ++p) s += partial[p * mn + o];
  __global float* c = C + c_off + (long)i * ldc + j;
  *c = beta == 0.0f ? alpha * s : fma(beta, *c, alpha * s);
}
