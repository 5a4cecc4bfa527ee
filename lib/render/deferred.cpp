#include "lib/render/deferred.hpp"

#include <string>

#include "host/error.hpp"
#include "host/launch.hpp"

namespace stylerf::render {

using host::Error;
using host::launch_with_local;

constexpr size_t kGroup = 64;  // per-ray kernels: many groups for the pthread device (see ray_march.cpp)

// Checks x [R, C] F32 and a [R] F32 (and each extra [R,C] / [R] tensor); returns C.
static int check_rows(const Tensor& x, const Tensor& a, const char* op, const char* xname) {
  host::expect_dtype(x, host::DType::F32, op, xname);
  if (x.ndim() != 2 || x.dim(1) < 1)
    throw Error(std::string(op) + ": " + xname + " has shape " + host::shape_str(x.shape()) + ", expected [R, C]");
  host::expect_shape(a, {x.dim(0)}, host::DType::F32, op, "opacity");
  return static_cast<int>(x.dim(1));
}

static size_t rounded(int64_t R) { return size_t((R + kGroup - 1) / kGroup * kGroup); }

Tensor opacity_normalise_forward(const Tensor& F, const Tensor& a, float eps) {
  const int C = check_rows(F, a, "opacity_normalise_forward", "features");
  if (!(eps > 0.0f)) throw Error("opacity_normalise_forward: eps must be positive");
  const int R = static_cast<int>(F.dim(0));
  Tensor n(F.shape(), "mean features");
  if (R > 0) launch_with_local("composite", "opacity_normalise_forward", "", {rounded(R)}, {kGroup}, F, a, R, C, eps, n);
  return n;
}

Tensor opacity_normalise_backward(const Tensor& F, const Tensor& a, const Tensor& dn, Tensor& da, float eps) {
  const int C = check_rows(F, a, "opacity_normalise_backward", "features");
  host::expect_shape(dn, F.shape(), host::DType::F32, "opacity_normalise_backward", "dn");
  host::expect_shape(da, a.shape(), host::DType::F32, "opacity_normalise_backward", "da");
  const int R = static_cast<int>(F.dim(0));
  Tensor dF(F.shape(), "d features");
  if (R > 0)
    launch_with_local("composite", "opacity_normalise_backward", "", {rounded(R)}, {kGroup}, F, a, dn, R, C, eps, dF, da);
  return dF;
}

Tensor opacity_scale_forward(const Tensor& c, const Tensor& a) {
  const int C = check_rows(c, a, "opacity_scale_forward", "values");
  const int R = static_cast<int>(c.dim(0));
  Tensor y(c.shape(), "opacity-scaled values");
  if (R > 0) launch_with_local("composite", "opacity_scale_forward", "", {rounded(R)}, {kGroup}, c, a, R, C, y);
  return y;
}

Tensor opacity_scale_backward(const Tensor& c, const Tensor& a, const Tensor& dy, Tensor& da) {
  const int C = check_rows(c, a, "opacity_scale_backward", "values");
  host::expect_shape(dy, c.shape(), host::DType::F32, "opacity_scale_backward", "dy");
  host::expect_shape(da, a.shape(), host::DType::F32, "opacity_scale_backward", "da");
  const int R = static_cast<int>(c.dim(0));
  Tensor dc(c.shape(), "d values");
  if (R > 0) launch_with_local("composite", "opacity_scale_backward", "", {rounded(R)}, {kGroup}, c, a, dy, R, C, dc, da);
  return dc;
}

}  // namespace stylerf::render
