// Winograd F(m x m, 3 x 3) for the stride-1 "same" 3x3 conv (kernels/winograd.cl has the transforms and
// their adjoints). Every image's tiles share one GEMM per transformed position xi:
//   forward   M[xi] [Cout, T] = U[xi] [Cout, Cin] x V[xi] [Cin, T]
//   dX        dV[xi] [Cin, T] = U[xi]^T x dM[xi]
//   dW        dU[xi] [Cout, Cin] = dM[xi] x V[xi]^T          (V recomputed from x, not kept from forward)
// The transformed tensors are pooled temporaries, returned when the call ends; the filters' transform U is
// kept instead when the caller hands in a cache (nn::ConvFilterCache, lib/nn/ops.hpp).
#include <algorithm>
#include <string>

#include "host/gemm.hpp"
#include "host/launch.hpp"
#include "lib/nn/conv_algo.hpp"
#include "lib/nn/conv_internal.hpp"
#include "lib/nn/ops.hpp"

namespace stylerf::nn::detail {
namespace {

using host::Trans;

struct Tiles {
  int m, alpha, th, tw, T;
  size_t groups;  // work-items along dimension 0 of the tile kernels: 8 tiles of a tile row each
  std::string options;
};

Tiles tiles_of(const ConvDims& d, int m) {
  Tiles t;
  t.m = m;
  t.alpha = m + 2;
  t.th = (d.H + m - 1) / m;
  t.tw = (d.W + m - 1) / m;
  t.T = d.N * t.th * t.tw;
  t.groups = size_t(d.N) * t.th * ((t.tw + 7) / 8);
  t.options = winograd_build_options(m);
  return t;
}

// The tile kernels keep alpha^2 float8 values per work-item in private arrays; PoCL's CPU driver lays a
// work-group's private arrays out side by side on its stack, so a driver-chosen work-group of hundreds of
// work-items overflows it (F(4x4): 36 x 3 float8 arrays a work-item). Eight work-items a group is enough
// to keep a CPU core busy and fits any stack; GPUs get 64 (one wavefront).
template <class... Args>
void launch_wino(const Tiles& t, const char* kernel, const host::Range& global, const Args&... args) {
  const bool cpu = host::Runtime::instance().device().type & CL_DEVICE_TYPE_CPU;
  host::launch_with_local("winograd", kernel, t.options, global, host::Range(cpu ? 8 : 64, 1), args...);
}

host::Tensor filter_transform(const Tiles& t, const ConvDims& d, const host::Tensor& w) {
  host::Tensor U({int64_t(t.alpha) * t.alpha, d.Cout, d.Cin}, "winograd filters");
  launch_wino(t, "wino_filter_transform", {size_t(d.Cin + 7) / 8, size_t(d.Cout)}, w, U, d.Cin, d.Cout);
  return U;
}

// w's transform: from the cache when one is given (made and kept there on a miss), else made for this call.
host::Tensor filters_of(const Tiles& t, const ConvDims& d, const host::Tensor& w, ConvFilterCache* cache) {
  if (!cache) return filter_transform(t, d, w);
  return cache->get(t.m, w, [&] { return filter_transform(t, d, w); });
}

host::Tensor input_transform(const Tiles& t, const ConvDims& d, const host::Tensor& x, int mode) {
  host::Tensor V({int64_t(t.alpha) * t.alpha, d.Cin, t.T}, "winograd input tiles");
  launch_wino(t, "wino_input_transform", {t.groups, size_t(d.Cin)}, x, V, d.Cin, d.H, d.W, t.th, t.tw, t.T, mode);
  return V;
}

// C[xi] = op(A[xi]) op(B[xi]) for every transformed position.
void batched_gemm(const Tiles& t, Trans ta, Trans tb, int M, int N, int K, const host::Tensor& A, int lda,
                  const host::Tensor& B, int ldb, host::Tensor& C, int ldc) {
  const size_t a_plane = size_t(M) * K, b_plane = size_t(K) * N, c_plane = size_t(M) * N;
  host::gemm_strided_batched(ta, tb, M, N, K, 1.0f, A.mem(), 0, lda, a_plane, B.mem(), 0, ldb, b_plane, 0.0f, C.mem(), 0,
                             ldc, c_plane, t.alpha * t.alpha);
}

}  // namespace

void winograd_forward(int m, const ConvDims& d, int mode, const host::Tensor& x, const host::Tensor& w,
                      const host::Tensor& b, host::Tensor& y, ConvFilterCache* filters) {
  const Tiles t = tiles_of(d, m);
  const host::Tensor U = filters_of(t, d, w, filters);
  const host::Tensor V = input_transform(t, d, x, mode);
  host::Tensor M({int64_t(t.alpha) * t.alpha, d.Cout, t.T}, "winograd output tiles");
  batched_gemm(t, Trans::No, Trans::No, d.Cout, t.T, d.Cin, U, d.Cin, V, t.T, M, t.T);
  launch_wino(t, "wino_output_transform", {t.groups, size_t(d.Cout)}, M, b.defined() ? b : M,
              b.defined() ? 1 : 0, y, d.Cout, d.H, d.W, t.th, t.tw, t.T);
}

void winograd_backward(int m, const ConvDims& d, int mode, const host::Tensor& x, const host::Tensor& w,
                       const host::Tensor& dy, host::Tensor* dx, host::Tensor* dw, ConvFilterCache* filters) {
  const Tiles t = tiles_of(d, m);
  host::Tensor dM({int64_t(t.alpha) * t.alpha, d.Cout, t.T}, "winograd output-tile gradient");
  launch_wino(t, "wino_output_backward", {t.groups, size_t(d.Cout)}, dy, dM, d.Cout, d.H, d.W, t.th, t.tw, t.T);
  if (dw) {
    const host::Tensor V = input_transform(t, d, x, mode);
    host::Tensor dU({int64_t(t.alpha) * t.alpha, d.Cout, d.Cin}, "winograd filter gradient");
    batched_gemm(t, Trans::No, Trans::Yes, d.Cout, d.Cin, t.T, dM, t.T, V, t.T, dU, d.Cin);
    launch_wino(t, "wino_filter_backward", {size_t(d.Cin + 7) / 8, size_t(d.Cout)}, dU, *dw, d.Cin, d.Cout);
  }
  if (dx) {
    const host::Tensor U = filters_of(t, d, w, filters);
    host::Tensor dV({int64_t(t.alpha) * t.alpha, d.Cin, t.T}, "winograd input-tile gradient");
    batched_gemm(t, Trans::Yes, Trans::No, d.Cin, t.T, d.Cout, U, d.Cin, dM, t.T, dV, t.T);
    launch_wino(t, "wino_input_backward", {t.groups, size_t(d.Cin)}, dV, d.Cin, t.th, t.tw, t.T);
    launch_wino(t, "wino_input_gather", {t.groups, size_t(d.Cin)}, dV, *dx, d.Cin, d.H, d.W, t.th, t.tw, t.T);
    if (mode == 1)  // reflect: the mirror rows and columns add their share
      launch_wino(t, "wino_input_gather_reflect", {size_t(std::max(d.W, d.H)), 4, size_t(d.N) * d.Cin}, dV, *dx,
                  d.Cin, d.H, d.W, t.th, t.tw, d.N);
  }
}

}  // namespace stylerf::nn::detail
