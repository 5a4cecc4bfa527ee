// Elementwise helpers used across ops.

// y = a*x + b*y
__kernel void axpby(__global const float* x, __global float* y, float a, float b, int n) {
  int i = get_global_id(0);
  if (i >= n) return;
  y[i] = a * x[i] + b * y[i];
}
