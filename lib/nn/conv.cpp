// conv2d, stride 1, "same" size, kernel 1 or 3, zero or reflect padding: im2col + GEMM.
//
//   forward  y_n[Cout, HW]   = W[Cout, CKK] x col_n[CKK, HW]              (+ bias)
//   dX       col_n[CKK, HW]  = W^T x dY_n, then col2im (a gather, no atomics)
//   dW       dW[Cout, CKK]  += dY_n[Cout, HW] x col_n^T                     (beta = 1 after image 0)
//   db       sum of dY over n and pixels
// CKK = Cin * k * k. With k = 1 the input itself is the col matrix, so im2col / col2im are skipped.
//
// The col matrix is large (decoder layer 1 at 256x256: 2304 x 65536 floats = 604 MB), so it is bounded:
// when one image's col would exceed the scratch limit (256 MiB, or STYLERF_CONV_SCRATCH_BYTES, never more
// than the device's max allocation) the image is processed in chunks of whole output rows; the GEMMs take
// offsets and leading dimensions into the full tensors. The scratch is a pooled temporary of each call.
// Those chunk loops are shared with the strided conv (detail::conv_chunked_forward / _backward); this file
// supplies its im2col / col2im kernels. 3x3 convs run Winograd unless asked otherwise (conv_algo.hpp,
// conv_winograd.cpp): this file's im2col path is then the fallback and the reference.
#include <algorithm>
#include <cstdlib>
#include <string>

#include "host/error.hpp"
#include "host/gemm.hpp"
#include "host/launch.hpp"
#include "lib/nn/columns.hpp"
#include "host/runtime.hpp"
#include "lib/nn/conv_internal.hpp"
#include "lib/nn/ops.hpp"

namespace stylerf::nn {
namespace {

using host::Error;
using host::Trans;

constexpr int kPadZero = 0, kPadReflect = 1;  // must match kernels/nn.cl

struct ConvGeom : detail::ConvDims {
  int mode;
  int64_t ckk() const { return int64_t(Cin) * K * K; }
  int64_t hw() const { return int64_t(H) * W; }
};

std::string dims(const Tensor& t) { return host::shape_str(t.shape()); }

ConvGeom check_conv(const char* op, const Tensor& x, const Tensor& w, Padding pad) {
  if (!x.defined() || !w.defined()) throw Error(std::string(op) + ": input and weight must be defined");
  if (x.ndim() != 4) throw Error(std::string(op) + ": input must be [N,Cin,H,W], got " + dims(x));
  if (w.ndim() != 4) throw Error(std::string(op) + ": weight must be [Cout,Cin,k,k], got " + dims(w));
  ConvGeom g{};
  detail::read_conv_dims(x, w, g);
  g.mode = pad == Padding::Reflect ? kPadReflect : kPadZero;
  if (w.dim(2) != w.dim(3) || (g.K != 1 && g.K != 3))
    throw Error(std::string(op) + ": kernel must be 1x1 or 3x3, weight has shape " + dims(w));
  detail::check_conv_dims(op, x, w, g);
  if (pad == Padding::Reflect && g.K == 3 && (g.H < 2 || g.W < 2))
    throw Error(std::string(op) + ": reflect padding needs H, W >= 2, input is " + dims(x));
  // Kernels index with int.
  const int64_t big = std::max({x.numel(), int64_t(g.N) * g.Cout * g.hw(), g.ckk() * g.hw()});
  if (big >= (int64_t(1) << 31))
    throw Error(std::string(op) + ": tensors too large for 32-bit indexing (input " + dims(x) + ", weight " +
                dims(w) + ")");
  return g;
}

// The im2col + GEMM shape for detail::conv_chunked_forward / _backward: output size = input size.
detail::ColGemmGeom col_gemm_geom(const ConvGeom& g) { return {g.N, g.Cout, int(g.ckk()), g.H, g.W, "W"}; }

void im2col(const Tensor& x, int n, const ConvGeom& g, cl_mem col, int y0, int rows) {
  host::launch("nn", "im2col", {size_t(rows), size_t(g.ckk())}, x, int(n * g.Cin * g.hw()), col, g.Cin, g.H, g.W,
               g.K, g.mode, y0, rows);
}

// Adds (or, for the first chunk, writes) the contributions of col rows [y0, y0+rows) into dx image n.
void col2im(cl_mem col, Tensor& dx, int n, const ConvGeom& g, int y0, int rows, bool accumulate) {
  // Input rows a chunk of output rows can reach: one row either side (reflected taps stay inside).
  const int ylo = accumulate ? std::max(0, y0 - 1) : 0;
  const int yhi = accumulate ? std::min(g.H, y0 + rows + 1) : g.H;
  host::launch("nn", "col2im", {size_t(yhi - ylo), size_t(g.Cin)}, col, dx, int(n * g.Cin * g.hw()), g.Cin, g.H,
               g.W, g.K, g.mode, y0, rows, ylo, yhi - ylo, accumulate ? 1 : 0);
}

}  // namespace

namespace detail {

void read_conv_dims(const Tensor& x, const Tensor& w, ConvDims& d) {
  d.N = int(x.dim(0));
  d.Cin = int(x.dim(1));
  d.H = int(x.dim(2));
  d.W = int(x.dim(3));
  d.Cout = int(w.dim(0));
  d.K = int(w.dim(2));
}

void check_conv_dims(const char* op, const Tensor& x, const Tensor& w, const ConvDims& d) {
  if (w.dim(1) != d.Cin)
    throw Error(std::string(op) + ": channel mismatch: input " + dims(x) + " has " + std::to_string(d.Cin) +
                " channels but weight " + dims(w) + " expects " + std::to_string(w.dim(1)));
  if (d.N < 1 || d.Cin < 1 || d.Cout < 1 || d.H < 1 || d.W < 1)
    throw Error(std::string(op) + ": empty input " + dims(x) + " or weight " + dims(w));
}

size_t conv_scratch_limit_bytes() {
  size_t limit = std::min(host::Runtime::instance().device().max_alloc_bytes, kConvScratchDefaultBytes);
  if (const char* env = std::getenv("STYLERF_CONV_SCRATCH_BYTES")) {
    long long v = std::atoll(env);
    if (v > 0) limit = std::min(host::Runtime::instance().device().max_alloc_bytes, static_cast<size_t>(v));
  }
  return limit;
}

Tensor conv_scratch(size_t floats) { return Tensor({int64_t(floats)}, "conv im2col scratch"); }

int conv_rows_per_chunk(const char* op, const ColGemmGeom& g) {
  const size_t row_bytes = size_t(g.ckk) * g.out_cols * sizeof(float);
  const size_t limit = conv_scratch_limit_bytes();
  if (row_bytes > limit)
    throw Error(std::string(op) + ": one output row of the im2col matrix needs " + std::to_string(row_bytes) +
                " bytes (Cin*k*k = " + std::to_string(g.ckk) + ", " + g.cols_name + " = " +
                std::to_string(g.out_cols) + "), more than the scratch limit of " + std::to_string(limit) + " bytes");
  return int(std::min<size_t>(g.out_rows, limit / row_bytes));
}

}  // namespace detail

void ConvFilterCache::clear() { entries_[0] = entries_[1] = Entry(); }

Tensor conv2d_forward(const Tensor& x, const Tensor& w, const Tensor& b, Padding pad, ConvAlgo algo,
                      ConvFilterCache* filters) {
  const ConvGeom g = check_conv("conv2d_forward", x, w, pad);
  if (b.defined()) expect_shape(b, {g.Cout}, "conv2d_forward", "bias");
  Tensor y({g.N, g.Cout, g.H, g.W}, "conv2d_forward output");
  const int hw = int(g.hw()), ckk = int(g.ckk());
  const ConvAlgo a = g.K == 3 ? resolve_conv_algo(algo, g.Cin, g.Cout, g.H, g.W, g.N) : ConvAlgo::Im2col;
  if (a == ConvAlgo::Winograd2 || a == ConvAlgo::Winograd4) {
    detail::winograd_forward(a == ConvAlgo::Winograd2 ? 2 : 4, g, g.mode, x, w, b, y, filters);
    return y;
  }
  if (g.K == 1) {
    // The input image [Cin, HW] is already the col matrix.
    for (int n = 0; n < g.N; ++n)
      host::gemm(Trans::No, Trans::No, g.Cout, hw, ckk, 1.0f, w.mem(), 0, ckk, x.mem(), size_t(n) * g.Cin * hw, hw,
                 0.0f, y.mem(), size_t(n) * g.Cout * hw, hw);
  } else {
    detail::conv_chunked_forward("conv2d_forward", col_gemm_geom(g), w.mem(), y.mem(),
                                 [&](cl_mem col, int n, int y0, int rows) { im2col(x, n, g, col, y0, rows); });
  }
  if (b.defined()) {
    host::launch("nn", "bias_add", {size_t((hw + 7) / 8), size_t(g.N) * g.Cout}, y, b, g.Cout, hw);
  }
  return y;
}

Conv2dGrads conv2d_backward(const Tensor& x, const Tensor& w, const Tensor& dy, Padding pad, bool need_dx,
                            bool need_params, ConvAlgo algo, ConvFilterCache* filters) {
  const ConvGeom g = check_conv("conv2d_backward", x, w, pad);
  expect_shape(dy, {g.N, g.Cout, g.H, g.W}, "conv2d_backward", "dy");
  Conv2dGrads out;
  if (!need_dx && !need_params) return out;
  const int hw = int(g.hw()), ckk = int(g.ckk());
  if (need_dx) out.dx = Tensor({g.N, g.Cin, g.H, g.W}, "conv2d_backward dx");
  if (need_params) {
    out.dw = Tensor(w.shape(), "conv2d_backward dw");
    out.db = image_channel_sum(dy);
  }

  const ConvAlgo a = g.K == 3 ? resolve_conv_algo(algo, g.Cin, g.Cout, g.H, g.W, g.N) : ConvAlgo::Im2col;
  if (a == ConvAlgo::Winograd2 || a == ConvAlgo::Winograd4) {
    detail::winograd_backward(a == ConvAlgo::Winograd2 ? 2 : 4, g, g.mode, x, w, dy, need_dx ? &out.dx : nullptr,
                              need_params ? &out.dw : nullptr, filters);
    return out;
  }
  if (g.K == 1) {
    for (int n = 0; n < g.N; ++n) {
      const size_t xo = size_t(n) * g.Cin * hw, yo = size_t(n) * g.Cout * hw;
      if (need_params)  // dW[Cout, Cin] (+)= dY_n [Cout, HW] x X_n^T
        host::gemm(Trans::No, Trans::Yes, g.Cout, ckk, hw, 1.0f, dy.mem(), yo, hw, x.mem(), xo, hw,
                   n == 0 ? 0.0f : 1.0f, out.dw.mem(), 0, ckk);
      if (need_dx)  // dX_n [Cin, HW] = W^T x dY_n
        host::gemm(Trans::Yes, Trans::No, ckk, hw, g.Cout, 1.0f, w.mem(), 0, ckk, dy.mem(), yo, hw, 0.0f,
                   out.dx.mem(), xo, hw);
    }
    return out;
  }

  detail::conv_chunked_backward(
      "conv2d_backward", col_gemm_geom(g), w.mem(), dy.mem(), need_params ? out.dw.mem() : nullptr, need_dx,
      [&](cl_mem col, int n, int y0, int rows) { im2col(x, n, g, col, y0, rows); },
      [&](cl_mem col, int n, int y0, int rows, bool accumulate) { col2im(col, out.dx, n, g, y0, rows, accumulate); });
  return out;
}

}  // namespace stylerf::nn
