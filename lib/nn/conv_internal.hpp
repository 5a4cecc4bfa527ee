// Internals shared by conv.cpp (stride-1 "same" conv2d) and conv_strided.cpp (general k x k conv with
// stride and zero padding), defined in conv.cpp: reading and checking the sizes both take from input and
// weight, the one process-wide im2col scratch buffer and its size limit, and the row-chunked im2col + GEMM
// loops both convs run (they differ only in their im2col / col2im kernels and in how input and output
// sizes relate, so those come in as callables and output sizes).
#pragma once
#include <CL/cl.h>

#include <algorithm>
#include <cstddef>

#include "host/gemm.hpp"
#include "host/tensor.hpp"

namespace stylerf::nn::detail {

// Sizes both convs read from input x [N, Cin, H, W] and weight w [Cout, Cin, K, K]; their geometry
// structs derive from it.
struct ConvDims {
  int N, Cin, Cout, H, W, K;
};

// Fills d from x and w (both 4-D: the caller has checked).
void read_conv_dims(const host::Tensor& x, const host::Tensor& w, ConvDims& d);

// Throws (naming `op`, x and w) when w's input channels are not x's, or when any size in d is < 1.
void check_conv_dims(const char* op, const host::Tensor& x, const host::Tensor& w, const ConvDims& d);

// The im2col scratch bound: 256 MiB, or STYLERF_CONV_SCRATCH_BYTES when set; never above the device's
// max allocation. 256 MiB keeps the col GEMMs large (decoder layer 1 at 256x256 runs in 3 chunks).
constexpr size_t kConvScratchDefaultBytes = size_t(256) << 20;
size_t conv_scratch_limit_bytes();

// A col scratch buffer of `floats` floats for one call: a pooled temporary (the runtime's buffer pool
// hands the same buffer to the next call), released when the caller's Tensor goes.
host::Tensor conv_scratch(size_t floats);

// A conv's im2col + GEMM shape per image, in output terms: image n's col matrix is
// [ckk, out_rows * out_cols], its output / dY slice [Cout, out_rows * out_cols].
struct ColGemmGeom {
  int N, Cout, ckk;    // ckk = Cin * k * k
  int out_rows, out_cols;
  const char* cols_name;  // what the caller calls out_cols ("W", "Wo"), for the error message
};

// Output rows per chunk so that a [ckk, rows * out_cols] col fits under the scratch limit; throws (naming
// `op`) when not even one row fits.
int conv_rows_per_chunk(const char* op, const ColGemmGeom& g);

// The loops below are templates on the callables (not std::function) so that the hot stride-1 conv compiles
// to the same straight loop of launches as before they were shared. Both process image by image, in chunks
// of whole output rows [row0, row0 + rows): the GEMMs take offsets and leading dimensions into the full
// tensors, so a chunk's output lands in place.

// Forward: y_n[Cout, rows*out_cols] = W[Cout, ckk] x col, per chunk, after im2col(col, n, row0, rows) fills
// col with the chunk's [ckk, rows * out_cols] matrix. No bias.
template <class Im2col>
void conv_chunked_forward(const char* op, const ColGemmGeom& g, cl_mem w, cl_mem y, Im2col&& im2col) {
  using host::Trans;
  const int chunk_rows = conv_rows_per_chunk(op, g);
  const int hw = g.out_rows * g.out_cols, ckk = g.ckk;
  const host::Tensor scratch = conv_scratch(size_t(ckk) * chunk_rows * g.out_cols);
  cl_mem col = scratch.mem();
  for (int n = 0; n < g.N; ++n) {
    for (int row0 = 0; row0 < g.out_rows; row0 += chunk_rows) {
      const int rows = std::min(chunk_rows, g.out_rows - row0), cols = rows * g.out_cols;
      im2col(col, n, row0, rows);
      host::gemm(Trans::No, Trans::No, g.Cout, cols, ckk, 1.0f, w, 0, ckk, col, 0, cols, 0.0f, y,
                 size_t(n) * g.Cout * hw + size_t(row0) * g.out_cols, hw);
    }
  }
}

// Backward without the bias: per chunk,
//   dW[Cout, ckk] (+)= dY chunk x col^T   (after im2col; written by the first chunk, added by the rest)
//   col = W^T x dY chunk, then col2im(col, n, row0, rows, accumulate = row0 > 0): the first chunk of an
//   image writes all of its dx, later ones add (neighbouring chunks can reach the same input rows).
// dw == nullptr skips the dW GEMMs (and the im2col); need_dx == false skips the dX GEMMs and col2im.
template <class Im2col, class Col2im>
void conv_chunked_backward(const char* op, const ColGemmGeom& g, cl_mem w, cl_mem dy, cl_mem dw, bool need_dx,
                           Im2col&& im2col, Col2im&& col2im) {
  using host::Trans;
  const int chunk_rows = conv_rows_per_chunk(op, g);
  const int hw = g.out_rows * g.out_cols, ckk = g.ckk;
  const host::Tensor scratch = conv_scratch(size_t(ckk) * chunk_rows * g.out_cols);
  cl_mem col = scratch.mem();
  bool first_dw = true;
  for (int n = 0; n < g.N; ++n) {
    for (int row0 = 0; row0 < g.out_rows; row0 += chunk_rows) {
      const int rows = std::min(chunk_rows, g.out_rows - row0), cols = rows * g.out_cols;
      const size_t yo = size_t(n) * g.Cout * hw + size_t(row0) * g.out_cols;
      if (dw) {
        im2col(col, n, row0, rows);
        host::gemm(Trans::No, Trans::Yes, g.Cout, ckk, cols, 1.0f, dy, yo, hw, col, 0, cols, first_dw ? 0.0f : 1.0f,
                   dw, 0, ckk);
        first_dw = false;
      }
      if (need_dx) {
        // The in-order queue finishes the dW GEMM before this overwrites col.
        host::gemm(Trans::Yes, Trans::No, ckk, cols, g.Cout, 1.0f, w, 0, ckk, dy, yo, hw, 0.0f, col, 0, cols);
        col2im(col, n, row0, rows, /*accumulate=*/row0 > 0);
      }
    }
  }
}

}  // namespace stylerf::nn::detail

namespace stylerf::nn {
class ConvFilterCache;
}

namespace stylerf::nn::detail {

// Winograd F(m x m, 3 x 3), m = 2 or 4 (lib/nn/conv_winograd.cpp): y = conv(x, w) + b (b may be
// undefined); dx and dw (either may be null) are overwritten. mode: 0 zero padding, 1 reflect. filters
// (may be null) keeps w's transform across calls (nn::ConvFilterCache).
void winograd_forward(int m, const ConvDims& d, int mode, const host::Tensor& x, const host::Tensor& w,
                      const host::Tensor& b, host::Tensor& y, ConvFilterCache* filters);
void winograd_backward(int m, const ConvDims& d, int mode, const host::Tensor& x, const host::Tensor& w,
                       const host::Tensor& dy, host::Tensor* dx, host::Tensor* dw, ConvFilterCache* filters);

}  // namespace stylerf::nn::detail
