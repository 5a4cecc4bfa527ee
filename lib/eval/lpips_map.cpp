#include "lib/eval/lpips_map.hpp"

#include <string>

#include "host/error.hpp"
#include "host/launch.hpp"

namespace stylerf::eval {
namespace {

using host::Error;
using host::Tensor;

// The kernels take 8 neighbouring positions per work-item.
size_t groups_of_8(int n) { return size_t((n + 7) / 8); }

struct MapGeom {
  int C, HW;
};

MapGeom check_map(const char* op, const Tensor& fa, const Tensor& fb, const Tensor& w) {
  host::expect_dtype(fa, host::DType::F32, op, "fa");
  if (fa.ndim() != 4 || fa.dim(0) != 1)
    throw Error(std::string(op) + ": fa must be [1,C,H,W], got " + host::shape_str(fa.shape()));
  host::expect_shape(fb, fa.shape(), host::DType::F32, op, "fb");
  host::expect_shape(w, {fa.dim(1)}, host::DType::F32, op, "w (one weight per channel)");
  if (fa.numel() == 0) throw Error(std::string(op) + ": empty features " + host::shape_str(fa.shape()));
  if (fa.numel() >= (int64_t(1) << 31))
    throw Error(std::string(op) + ": features " + host::shape_str(fa.shape()) + " too large for 32-bit indexing");
  return {int(fa.dim(1)), int(fa.dim(2) * fa.dim(3))};
}

}  // namespace

Tensor lpips_distance_map(const Tensor& fa, const Tensor& fb, const Tensor& w) {
  const MapGeom g = check_map("lpips_distance_map", fa, fb, w);
  Tensor d({int64_t(g.HW)}, "lpips_distance_map output");
  host::launch("lpips", "lpips_distance_forward", {groups_of_8(g.HW)}, fa, fb, w, d, g.C, g.HW);
  return d;
}

Tensor lpips_distance_map_backward(const Tensor& fa, const Tensor& fb, const Tensor& w, const Tensor& dd) {
  const MapGeom g = check_map("lpips_distance_map_backward", fa, fb, w);
  host::expect_shape(dd, {int64_t(g.HW)}, host::DType::F32, "lpips_distance_map_backward", "dd");
  Tensor da(fa.shape(), "lpips_distance_map_backward da");
  host::launch("lpips", "lpips_distance_backward", {groups_of_8(g.HW)}, fa, fb, w, dd, da, g.C, g.HW);
  return da;
}

}  // namespace stylerf::eval
