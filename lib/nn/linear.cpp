// y = x W + b: one GEMM and a bias kernel forward; two GEMMs and a column sum backward.
//
//   forward  y[N,out]  = x[N,in] W[in,out]          then y[n,:] += b
//   dx       dx[N,in]  = dy[N,out] W^T
//   dW       dW[in,out] (+)= x^T dy                 (beta 1 accumulates straight into a Param's grad)
//   db       db[out]   (+)= sum_n dy[n,:]
#include "lib/nn/linear.hpp"

#include <string>

#include "host/error.hpp"
#include "host/gemm.hpp"
#include "host/launch.hpp"
#include "lib/nn/columns.hpp"

namespace stylerf::nn {
namespace {

using host::Error;
using host::Trans;

struct LinearDims {
  int n, in, out;
};

LinearDims check_linear(const char* op, const Tensor& x, const Tensor& w) {
  if (!x.defined()) throw Error(std::string(op) + ": x is undefined");
  if (!w.defined()) throw Error(std::string(op) + ": W is undefined");
  if (x.ndim() != 2) throw Error(std::string(op) + ": x must be [N, in], got " + host::shape_str(x.shape()));
  if (w.ndim() != 2) throw Error(std::string(op) + ": W must be [in, out], got " + host::shape_str(w.shape()));
  if (x.dim(0) == 0)
    throw Error(std::string(op) + ": x " + host::shape_str(x.shape()) +
                " has no rows; skip an empty batch before calling (device tensors cannot be empty)");
  if (x.dim(1) != w.dim(0))
    throw Error(std::string(op) + ": x " + host::shape_str(x.shape()) + " has " + std::to_string(x.dim(1)) +
                " columns but W " + host::shape_str(w.shape()) + " has " + std::to_string(w.dim(0)) + " rows");
  if (w.numel() == 0) throw Error(std::string(op) + ": W " + host::shape_str(w.shape()) + " is empty");
  // Tensor refuses >= 2^31 elements, and every dimension is at most a tensor's numel: ints suffice.
  return {int(x.dim(0)), int(x.dim(1)), int(w.dim(1))};
}

// dx (returned when need_dx), and dW / db into dw / db with GEMM beta (0 overwrite, 1 accumulate); a null
// dw / db skips that gradient.
Tensor backward_into(const char* op, const Tensor& x, const Tensor& w, const Tensor& dy, bool need_dx, Tensor* dw,
                     Tensor* db, bool accumulate) {
  const LinearDims d = check_linear(op, x, w);
  host::expect_shape(dy, {d.n, d.out}, op, "dy");
  const float beta = accumulate ? 1.0f : 0.0f;
  if (dw) {
    host::expect_shape(*dw, w.shape(), op, "dW");
    host::gemm(Trans::Yes, Trans::No, d.in, d.out, d.n, 1.0f, x.mem(), 0, d.in, dy.mem(), 0, d.out, beta, dw->mem(), 0,
               d.out);
  }
  if (db) {
    host::expect_shape(*db, {d.out}, op, "db");
    // Summed over blocks of rows first (lib/nn/columns.hpp): one work-item a column group over all rows
    // took a second for SICT's ~3M points on an H100.
    nn::column_sum_into(dy, *db, accumulate);
  }
  if (!need_dx) return Tensor();
  Tensor dx({d.n, d.in}, std::string(op) + " dx");
  host::gemm(Trans::No, Trans::Yes, d.n, d.in, d.out, 1.0f, dy.mem(), 0, d.out, w.mem(), 0, d.out, 0.0f, dx.mem(), 0,
             d.in);
  return dx;
}

}  // namespace

Tensor linear_forward(const Tensor& x, const Tensor& w, const Tensor& b) {
  const LinearDims d = check_linear("linear_forward", x, w);
  if (b.defined()) host::expect_shape(b, {d.out}, "linear_forward", "bias");
  Tensor y({d.n, d.out}, "linear_forward output");
  host::gemm(Trans::No, Trans::No, d.n, d.out, d.in, 1.0f, x.mem(), 0, d.in, w.mem(), 0, d.out, 0.0f, y.mem(), 0,
             d.out);
  if (b.defined()) linear_add_bias(y, b);
  return y;
}

void linear_add_bias(Tensor& y, const Tensor& b) {
  if (!y.defined() || y.ndim() != 2) throw Error("linear_add_bias: y must be [N, out]");
  const int n = int(y.dim(0)), out = int(y.dim(1));
  host::expect_shape(b, {out}, "linear_add_bias", "bias");
  host::launch("linear", "linear_bias_add", {size_t((out + 7) / 8), size_t(n)}, y, b, n, out);
}

LinearGrads linear_backward(const Tensor& x, const Tensor& w, const Tensor& dy, bool need_dx, bool need_dw,
                            bool need_db) {
  const LinearDims d = check_linear("linear_backward", x, w);  // before allocating anything
  LinearGrads g;
  if (need_dw) g.dw = Tensor(w.shape(), "linear_backward dW");
  if (need_db) g.db = Tensor({d.out}, "linear_backward db");
  g.dx = backward_into("linear_backward", x, w, dy, need_dx, need_dw ? &g.dw : nullptr, need_db ? &g.db : nullptr,
                       /*accumulate=*/false);
  return g;
}

Tensor linear_backward(const Tensor& x, Param& w, Param* b, const Tensor& dy, bool need_dx) {
  const LinearDims d = check_linear("linear_backward", x, w.value);  // before a gradient is allocated
  host::expect_shape(dy, {d.n, d.out}, "linear_backward", "dy");
  if (b) host::expect_shape(b->value, {d.out}, "linear_backward", "bias");
  return backward_into("linear_backward", x, w.value, dy, need_dx, &w.grad_buffer(), b ? &b->grad_buffer() : nullptr,
                       /*accumulate=*/true);
}

}  // namespace stylerf::nn
