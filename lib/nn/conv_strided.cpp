// General conv2d: k x k kernel (any k >= 1), stride s >= 1, zero padding p >= 0, floored output size,
// by im2col + GEMM (kernels/strided.cl), the same scheme as conv.cpp:
//
//   forward  y_n[Cout, HoWo]  = W[Cout, CKK] x col_n[CKK, HoWo]          (+ bias)
//   dX       col_n[CKK, HoWo] = W^T x dY_n, then col2im (a gather per input row, no atomics)
//   dW       dW[Cout, CKK]   += dY_n[Cout, HoWo] x col_n^T               (beta = 1 after the first chunk)
//   db       sum of dY over n and pixels
//
// CKK = Cin * k * k. The col scratch and the row-chunk loops are shared with conv.cpp (conv_internal.hpp);
// this file supplies its im2col / col2im kernels. When one image's col exceeds the scratch limit the image
// is processed in chunks of whole output rows, as conv2d does. A chunk of output rows [oy0, oy0 + rows)
// reads input rows [oy0 s - p, (oy0 + rows - 1) s - p + k), so with s < k neighbouring chunks share input
// rows: the first chunk writes all of dx, later ones add.
#include <algorithm>
#include <string>

#include "host/error.hpp"
#include "host/launch.hpp"
#include "lib/nn/columns.hpp"
#include "lib/nn/conv_internal.hpp"
#include "lib/nn/ops.hpp"

namespace stylerf::nn {
namespace {

using host::Error;

struct Geom : detail::ConvDims {
  int S, P, Ho, Wo;
  int64_t ckk() const { return int64_t(Cin) * K * K; }
  int64_t hw() const { return int64_t(H) * W; }
  int64_t howo() const { return int64_t(Ho) * Wo; }
};

std::string dims(const Tensor& t) { return host::shape_str(t.shape()); }

Geom check_geom(const char* op, const Tensor& x, const Tensor& w, int stride, int pad) {
  const std::string o(op);
  if (!x.defined() || !w.defined()) throw Error(o + ": input and weight must be defined");
  if (x.ndim() != 4) throw Error(o + ": input must be [N,Cin,H,W], got " + dims(x));
  if (w.ndim() != 4 || w.dim(2) != w.dim(3) || w.dim(2) < 1)
    throw Error(o + ": weight must be [Cout,Cin,k,k] with k >= 1, got " + dims(w));
  if (stride < 1) throw Error(o + ": stride must be >= 1, got " + std::to_string(stride));
  if (pad < 0) throw Error(o + ": padding must be >= 0, got " + std::to_string(pad));
  Geom g{};
  detail::read_conv_dims(x, w, g);
  g.S = stride;
  g.P = pad;
  detail::check_conv_dims(op, x, w, g);
  if (int64_t(g.K) > int64_t(g.H) + 2 * int64_t(pad) || int64_t(g.K) > int64_t(g.W) + 2 * int64_t(pad))
    throw Error(o + ": the " + std::to_string(g.K) + "x" + std::to_string(g.K) + " kernel is larger than the input " +
                std::to_string(g.H) + "x" + std::to_string(g.W) + " (H x W) padded by " + std::to_string(pad) +
                " on each side (" + std::to_string(int64_t(g.H) + 2 * pad) + "x" +
                std::to_string(int64_t(g.W) + 2 * pad) + "): no output position");
  g.Ho = conv2d_output_size(g.H, g.K, stride, pad);
  g.Wo = conv2d_output_size(g.W, g.K, stride, pad);
  // Kernels index with int (padded coordinates included).
  const int64_t big = std::max({x.numel(), int64_t(g.N) * g.Cout * g.howo(), g.ckk() * g.howo(),
                                int64_t(g.H) + 2 * int64_t(pad) + g.K, int64_t(g.W) + 2 * int64_t(pad) + g.K});
  if (big >= (int64_t(1) << 31))
    throw Error(o + ": tensors too large for 32-bit indexing (input " + dims(x) + ", weight " + dims(w) + ")");
  return g;
}

// The im2col + GEMM shape for detail::conv_chunked_forward / _backward: chunks of output rows (Ho x Wo).
detail::ColGemmGeom col_gemm_geom(const Geom& g) { return {g.N, g.Cout, int(g.ckk()), g.Ho, g.Wo, "Wo"}; }

void im2col(const Tensor& x, int n, const Geom& g, cl_mem col, int oy0, int rows) {
  host::launch("strided", "im2col_strided", {size_t(rows), size_t(g.ckk())}, x, int(n * g.Cin * g.hw()), col, g.Cin,
               g.H, g.W, g.K, g.S, g.P, g.Wo, oy0, rows);
}

// Writes (first chunk: every input row) or adds (later chunks: the rows the chunk reaches) the
// contributions of col rows for output rows [oy0, oy0 + rows) into dx image n.
void col2im(cl_mem col, Tensor& dx, int n, const Geom& g, int oy0, int rows, bool accumulate) {
  int ylo = 0, yhi = g.H;
  if (accumulate) {
    ylo = std::max(0, oy0 * g.S - g.P);
    yhi = std::min(g.H, (oy0 + rows - 1) * g.S - g.P + g.K);
    if (yhi <= ylo) return;  // the chunk reads only padding
  }
  host::launch("strided", "col2im_strided", {size_t(yhi - ylo), size_t(g.Cin)}, col, dx, int(n * g.Cin * g.hw()),
               g.Cin, g.H, g.W, g.K, g.S, g.P, g.Wo, oy0, rows, ylo, yhi - ylo, accumulate ? 1 : 0);
}

}  // namespace

int conv2d_output_size(int in, int k, int stride, int pad) {
  if (stride < 1) throw Error("conv2d_output_size: stride must be >= 1, got " + std::to_string(stride));
  const int64_t span = int64_t(in) + 2 * int64_t(pad) - k;
  if (span < 0) return 0;
  return int(span / stride + 1);
}

Tensor conv2d_strided_forward(const Tensor& x, const Tensor& w, const Tensor& b, int stride, int pad) {
  const Geom g = check_geom("conv2d_strided_forward", x, w, stride, pad);
  if (b.defined()) expect_shape(b, {g.Cout}, "conv2d_strided_forward", "bias");
  Tensor y({g.N, g.Cout, g.Ho, g.Wo}, "conv2d_strided_forward output");
  const int howo = int(g.howo());
  detail::conv_chunked_forward("conv2d_strided_forward", col_gemm_geom(g), w.mem(), y.mem(),
                               [&](cl_mem col, int n, int oy0, int rows) { im2col(x, n, g, col, oy0, rows); });
  if (b.defined())
    host::launch("nn", "bias_add", {size_t((howo + 7) / 8), size_t(g.N) * g.Cout}, y, b, g.Cout, howo);
  return y;
}

Conv2dGrads conv2d_strided_backward(const Tensor& x, const Tensor& w, const Tensor& dy, int stride, int pad,
                                    bool need_dx, bool need_params) {
  const Geom g = check_geom("conv2d_strided_backward", x, w, stride, pad);
  expect_shape(dy, {g.N, g.Cout, g.Ho, g.Wo}, "conv2d_strided_backward", "dy");
  Conv2dGrads out;
  if (!need_dx && !need_params) return out;
  if (need_dx) out.dx = Tensor({g.N, g.Cin, g.H, g.W}, "conv2d_strided_backward dx");
  if (need_params) {
    out.dw = Tensor(w.shape(), "conv2d_strided_backward dw");
    out.db = image_channel_sum(dy);
  }
  detail::conv_chunked_backward(
      "conv2d_strided_backward", col_gemm_geom(g), w.mem(), dy.mem(), need_params ? out.dw.mem() : nullptr, need_dx,
      [&](cl_mem col, int n, int oy0, int rows) { im2col(x, n, g, col, oy0, rows); },
      [&](cl_mem col, int n, int oy0, int rows, bool accumulate) {
        col2im(col, out.dx, n, g, oy0, rows, accumulate);
      });
  return out;
}

}  // namespace stylerf::nn
