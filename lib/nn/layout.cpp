// [R,C] <-> [1,C,H,W] with one tiled transpose kernel (kernels/layout.cl).
#include "lib/nn/layout.hpp"

#include <string>

#include "host/error.hpp"
#include "host/launch.hpp"

namespace stylerf::nn {
namespace {

using host::Error;

constexpr int kTile = 16;  // TILE in kernels/layout.cl

// dst[c, r] = src[r, c] for src [rows, cols] (both contiguous).
Tensor transpose(const Tensor& src, int rows, int cols, host::Shape dst_shape, const char* op) {
  Tensor dst(std::move(dst_shape), std::string(op) + " output");
  host::launch("layout", "transpose2d", {size_t((rows + kTile - 1) / kTile), size_t((cols + kTile - 1) / kTile)}, src,
               0, dst, 0, rows, cols);
  return dst;
}

void check_defined(const Tensor& t, const char* op, const char* name) {
  if (!t.defined()) throw Error(std::string(op) + ": " + name + " is undefined");
}

void check_hw(int H, int W, const char* op) {
  if (H < 1 || W < 1)
    throw Error(std::string(op) + ": image size must be at least 1x1, got H = " + std::to_string(H) +
                ", W = " + std::to_string(W));
}

// rows [H*W, C] -> C, with errors naming the op.
int rows_channels(const Tensor& rows, int H, int W, const char* op) {
  check_defined(rows, op, "rows");
  check_hw(H, W, op);
  if (rows.ndim() != 2 || rows.dim(1) < 1)
    throw Error(std::string(op) + ": rows must be [R, C] with C >= 1, got " + host::shape_str(rows.shape()));
  if (rows.dim(0) != int64_t(H) * W)
    throw Error(std::string(op) + ": rows " + host::shape_str(rows.shape()) + " has " + std::to_string(rows.dim(0)) +
                " rows but the image is " + std::to_string(H) + "x" + std::to_string(W) + " = " +
                std::to_string(int64_t(H) * W) + " pixels");
  return int(rows.dim(1));
}

void check_image(const Tensor& image, const char* op, const char* name) {
  check_defined(image, op, name);
  if (image.ndim() != 4 || image.dim(0) != 1 || image.numel() == 0)
    throw Error(std::string(op) + ": " + name + " must be a non-empty [1, C, H, W], got " +
                host::shape_str(image.shape()));
}

}  // namespace

// ---- rows -> image -----------------------------------------------------------------------------------
Tensor rows_to_image(const Tensor& rows, int H, int W) {
  const int C = rows_channels(rows, H, W, "rows_to_image");
  return transpose(rows, H * W, C, {1, C, H, W}, "rows_to_image");
}

Tensor rows_to_image_backward(const Tensor& dimage) {
  check_image(dimage, "rows_to_image_backward", "dimage");
  const int C = int(dimage.dim(1)), hw = int(dimage.dim(2) * dimage.dim(3));
  return transpose(dimage, C, hw, {hw, C}, "rows_to_image_backward");
}

// ---- image -> rows -----------------------------------------------------------------------------------
Tensor image_to_rows(const Tensor& image) {
  check_image(image, "image_to_rows", "image");
  const int C = int(image.dim(1)), hw = int(image.dim(2) * image.dim(3));
  return transpose(image, C, hw, {hw, C}, "image_to_rows");
}

Tensor image_to_rows_backward(const Tensor& drows, int H, int W) {
  const int C = rows_channels(drows, H, W, "image_to_rows_backward");
  return transpose(drows, H * W, C, {1, C, H, W}, "image_to_rows_backward");
}

// ---- column blocks -----------------------------------------------------------------------------------------
namespace {
// Rows of a [R, C] matrix, with errors naming the op.
int64_t matrix_rows(const Tensor& t, const char* op, const char* name) {
  check_defined(t, op, name);
  if (t.ndim() != 2) throw Error(std::string(op) + ": " + name + " must be [R, C], got " + host::shape_str(t.shape()));
  return t.dim(0);
}

void copy_columns(const Tensor& src, int src_col, Tensor& dst, int dst_col, int n) {
  const int64_t rows = src.dim(0);
  if (rows == 0 || n == 0) return;
  host::launch("layout", "copy_columns", {size_t((n + 7) / 8), size_t(rows)}, src, int(src.dim(1)), src_col, dst,
               int(dst.dim(1)), dst_col, n, int(rows));
}
}  // namespace

Tensor concat_columns(const Tensor& a, const Tensor& b) {
  const int64_t R = matrix_rows(a, "concat_columns", "a");
  if (matrix_rows(b, "concat_columns", "b") != R)
    throw Error("concat_columns: a " + host::shape_str(a.shape()) + " and b " + host::shape_str(b.shape()) +
                " differ in rows");
  const int A = int(a.dim(1)), B = int(b.dim(1));
  Tensor out({R, int64_t(A) + B}, "concatenated columns");
  copy_columns(a, 0, out, 0, A);
  copy_columns(b, 0, out, A, B);
  return out;
}

Tensor take_columns(const Tensor& x, int from, int count) {
  const int64_t R = matrix_rows(x, "take_columns", "x");
  if (from < 0 || count < 0 || int64_t(from) + count > x.dim(1))
    throw Error("take_columns: columns [" + std::to_string(from) + ", " + std::to_string(from + count) + ") of " +
                host::shape_str(x.shape()));
  Tensor out({R, count}, "taken columns");
  copy_columns(x, from, out, 0, count);
  return out;
}

Tensor take_columns_backward(const Tensor& dy, int from, int width) {
  const int64_t R = matrix_rows(dy, "take_columns_backward", "dy");
  if (from < 0 || int64_t(from) + dy.dim(1) > width)
    throw Error("take_columns_backward: " + host::shape_str(dy.shape()) + " at column " + std::to_string(from) +
                " does not fit " + std::to_string(width) + " columns");
  Tensor dx = Tensor::zeros({R, width}, "take_columns gradient");
  copy_columns(dy, 0, dx, from, int(dy.dim(1)));
  return dx;
}

}  // namespace stylerf::nn
