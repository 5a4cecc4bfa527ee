// Pointwise and spatial ops: relu, 2x2 max pooling, x2 nearest upsampling (kernels/nn.cl); k x k max pooling
// with stride (kernels/strided.cl).
#include <string>

#include "host/error.hpp"
#include "host/launch.hpp"
#include "lib/nn/ops.hpp"

namespace stylerf::nn {
namespace {

using host::Error;

void check_defined(const Tensor& t, const char* op, const char* name) {
  if (!t.defined()) throw Error(std::string(op) + ": " + name + " is undefined");
}

void check_int_size(const Tensor& t, const char* op) {
  if (t.numel() >= (int64_t(1) << 31))
    throw Error(std::string(op) + ": tensor " + host::shape_str(t.shape()) + " too large for 32-bit indexing");
}

// [N,C,H,W] as (N*C, H, W).
struct Planes {
  int nc, h, w;
};

Planes planes_of(const Tensor& x, const char* op) {
  check_defined(x, op, "input");
  if (x.ndim() != 4) throw Error(std::string(op) + ": input must be [N,C,H,W], got " + host::shape_str(x.shape()));
  check_int_size(x, op);
  return {int(x.dim(0) * x.dim(1)), int(x.dim(2)), int(x.dim(3))};
}

size_t groups_of_8(int64_t n) { return size_t((n + 7) / 8); }

}  // namespace

// ---- relu ----------------------------------------------------------------------------------------
Tensor relu_forward(const Tensor& x) {
  check_defined(x, "relu_forward", "input");
  check_int_size(x, "relu_forward");
  Tensor y(x.shape(), "relu_forward output");
  host::launch("nn", "relu_forward", {groups_of_8(x.numel())}, x, y, int(x.numel()));
  return y;
}

Tensor relu_backward(const Tensor& y, const Tensor& dy) {
  check_defined(y, "relu_backward", "y");
  expect_shape(dy, y.shape(), "relu_backward", "dy");
  check_int_size(y, "relu_backward");
  Tensor dx(y.shape(), "relu_backward dx");
  host::launch("nn", "relu_backward", {groups_of_8(y.numel())}, y, dy, dx, int(y.numel()));
  return dx;
}

// ---- 2x2 max pooling -----------------------------------------------------------------------------
namespace {
// Odd sizes floor, like torch's MaxPool2d(2): the last row / column then belongs to no window.
Planes pool_planes(const Tensor& x, const char* op) {
  Planes p = planes_of(x, op);
  if (p.h < 2 || p.w < 2)
    throw Error(std::string(op) + ": 2x2 pooling needs H and W >= 2, input is " + host::shape_str(x.shape()));
  return p;
}
}  // namespace

Tensor maxpool2x2_forward(const Tensor& x) {
  const Planes p = pool_planes(x, "maxpool2x2_forward");
  Tensor y({x.dim(0), x.dim(1), p.h / 2, p.w / 2}, "maxpool2x2_forward output");
  host::launch("nn", "maxpool2x2_forward", {size_t(p.h / 2), size_t(p.nc)}, x, y, p.h, p.w);
  return y;
}

Tensor maxpool2x2_backward(const Tensor& x, const Tensor& dy) {
  const Planes p = pool_planes(x, "maxpool2x2_backward");
  expect_shape(dy, {x.dim(0), x.dim(1), p.h / 2, p.w / 2}, "maxpool2x2_backward", "dy");
  // The kernel writes every element of every window; with an odd H or W the last row / column is in none
  // and is left unwritten, so only then does dx need clearing first.
  const bool odd = p.h % 2 != 0 || p.w % 2 != 0;
  Tensor dx = odd ? Tensor::zeros(x.shape(), "maxpool2x2_backward dx") : Tensor(x.shape(), "maxpool2x2_backward dx");
  host::launch("nn", "maxpool2x2_backward", {size_t(p.h / 2), size_t(p.nc)}, x, dy, dx, p.h, p.w);
  return dx;
}

// ---- k x k max pooling, stride s (kernels/strided.cl) ------------------------------------------------
namespace {
struct PoolGeom {
  Planes p;
  int ho, wo;
};

PoolGeom pool_geom(const Tensor& x, int k, int stride, const char* op) {
  const Planes p = planes_of(x, op);
  if (k < 1 || stride < 1)
    throw Error(std::string(op) + ": window and stride must be >= 1, got " + std::to_string(k) + " and " +
                std::to_string(stride));
  if (p.h < k || p.w < k)
    throw Error(std::string(op) + ": " + std::to_string(k) + "x" + std::to_string(k) + " pooling needs H and W >= " +
                std::to_string(k) + ", input is " + host::shape_str(x.shape()));
  return {p, (p.h - k) / stride + 1, (p.w - k) / stride + 1};
}
}  // namespace

Tensor maxpool_forward(const Tensor& x, int k, int stride) {
  const PoolGeom g = pool_geom(x, k, stride, "maxpool_forward");
  Tensor y({x.dim(0), x.dim(1), g.ho, g.wo}, "maxpool_forward output");
  host::launch("strided", "maxpool_forward", {size_t(g.ho), size_t(g.p.nc)}, x, y, g.p.h, g.p.w, k, stride, g.ho,
               g.wo);
  return y;
}

Tensor maxpool_backward(const Tensor& x, const Tensor& dy, int k, int stride) {
  const PoolGeom g = pool_geom(x, k, stride, "maxpool_backward");
  expect_shape(dy, {x.dim(0), x.dim(1), g.ho, g.wo}, "maxpool_backward", "dy");
  Tensor dx(x.shape(), "maxpool_backward dx");  // the kernel writes every row
  host::launch("strided", "maxpool_backward", {size_t(g.p.h), size_t(g.p.nc)}, x, dy, dx, g.p.h, g.p.w, k, stride,
               g.ho, g.wo);
  return dx;
}

// ---- polyphase 2x2 max pooling and its interleave -------------------------------------------------
namespace {
// Every phase has the same H/2 x W/2 windows only when both sides are even.
Planes even_planes(const Tensor& x, const char* op, const char* name) {
  const Planes p = planes_of(x, op);
  if (p.h % 2 || p.w % 2 || p.h < 2 || p.w < 2)
    throw Error(std::string(op) + ": " + name + " must have even H and W >= 2, got " + host::shape_str(x.shape()));
  return p;
}
}  // namespace

Tensor maxpool2x2_phases_forward(const Tensor& x) {
  const Planes p = even_planes(x, "maxpool2x2_phases_forward", "the input");
  Tensor y({4 * x.dim(0), x.dim(1), p.h / 2, p.w / 2}, "maxpool2x2_phases_forward output");
  check_int_size(y, "maxpool2x2_phases_forward");
  host::launch("nn", "maxpool2x2_phases_forward", {size_t(p.h / 2) * size_t(p.w / 2), 4 * size_t(p.nc)}, x, y,
               p.nc, p.h, p.w);
  return y;
}

Tensor maxpool2x2_phases_backward(const Tensor& x, const Tensor& dy) {
  const Planes p = even_planes(x, "maxpool2x2_phases_backward", "the input");
  expect_shape(dy, {4 * x.dim(0), x.dim(1), p.h / 2, p.w / 2}, "maxpool2x2_phases_backward", "dy");
  Tensor dx(x.shape(), "maxpool2x2_phases_backward dx");
  host::launch("nn", "maxpool2x2_phases_backward", {size_t(p.h) * size_t(p.w), size_t(p.nc)}, x, dy, dx, p.nc,
               p.h, p.w);
  return dx;
}

Tensor phase_interleave_forward(const Tensor& x) {
  const Planes p = planes_of(x, "phase_interleave_forward");
  if (x.dim(0) % 4)
    throw Error("phase_interleave_forward: the batch must hold 4 phase blocks, got " + host::shape_str(x.shape()));
  const int nc = p.nc / 4;
  Tensor y({x.dim(0) / 4, x.dim(1), 2 * int64_t(p.h), 2 * int64_t(p.w)}, "phase_interleave_forward output");
  host::launch("nn", "phase_interleave_forward", {4 * size_t(p.h) * size_t(p.w), size_t(nc)}, x, y, nc, p.h, p.w);
  return y;
}

Tensor phase_interleave_backward(const Tensor& dy) {
  const Planes p = even_planes(dy, "phase_interleave_backward", "dy");
  Tensor dx({4 * dy.dim(0), dy.dim(1), p.h / 2, p.w / 2}, "phase_interleave_backward dx");
  host::launch("nn", "phase_interleave_backward", {size_t(p.h / 2) * size_t(p.w / 2), 4 * size_t(p.nc)}, dy, dx,
               p.nc, p.h / 2, p.w / 2);
  return dx;
}

// ---- x2 nearest upsampling -----------------------------------------------------------------------
Tensor upsample2x_forward(const Tensor& x) {
  const Planes p = planes_of(x, "upsample2x_forward");
  Tensor y({x.dim(0), x.dim(1), 2 * int64_t(p.h), 2 * int64_t(p.w)}, "upsample2x_forward output");
  check_int_size(y, "upsample2x_forward");
  host::launch("nn", "upsample2x_forward", {size_t(p.h), size_t(p.nc)}, x, y, p.h, p.w);
  return y;
}

Tensor upsample2x_backward(const Tensor& dy) {
  const Planes p = planes_of(dy, "upsample2x_backward");
  if (p.h % 2 != 0 || p.w % 2 != 0)
    throw Error("upsample2x_backward: dy must have even H and W, got " + host::shape_str(dy.shape()));
  Tensor dx({dy.dim(0), dy.dim(1), p.h / 2, p.w / 2}, "upsample2x_backward dx");
  host::launch("nn", "upsample2x_backward", {size_t(p.h / 2), size_t(p.nc)}, dy, dx, p.h / 2, p.w / 2);
  return dx;
}

}  // namespace stylerf::nn
