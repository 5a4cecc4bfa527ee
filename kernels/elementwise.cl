// Elementwise helpers used across ops.

// y = a*x + b*y, one element per work-item (the runtime's smoke tests launch it directly).
__kernel void axpby(__global const float* x, __global float* y, float a, float b, int n) {
  int i = get_global_id(0);
  if (i >= n) return;
  y[i] = a * x[i] + b * y[i];
}

// y = a*x + b*y, 64 elements per work-item (float8 loop), tail element by element. With b == 0, y is
// not read (BLAS convention): y may hold garbage or NaN and is simply overwritten with a*x.
__kernel void axpby64(__global const float* x, __global float* y, float a, float b, int n) {
  int i = get_global_id(0) * 64;
  if (i >= n) return;
  const int end = min(i + 64, n);
  if (b == 0.0f) {
    for (; i + 8 <= end; i += 8) vstore8(a * vload8(0, x + i), 0, y + i);
    for (; i < end; ++i) y[i] = a * x[i];
  } else {
    for (; i + 8 <= end; i += 8) vstore8(fma(b, vload8(0, y + i), a * vload8(0, x + i)), 0, y + i);
    for (; i < end; ++i) y[i] = fma(b, y[i], a * x[i]);
  }
}
