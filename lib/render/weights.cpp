#include "lib/render/weights.hpp"

#include "host/error.hpp"
#include "host/launch.hpp"

namespace stylerf::render {

using host::launch_with_local;

// Per-ray kernels in groups of 64 (see lib/render/composite.cpp for why not the driver's choice).
constexpr size_t kGroup = 64;

static const Tensor& absent() {
  static Tensor t = Tensor::zeros({1}, "absent input");
  return t;
}

Weights weights_forward(const Samples& s, const Tensor& sigma) {
  const int R = static_cast<int>(check_ray_lists(s.ray_offset, s.ray_count, "weights_forward"));
  host::expect_shape(sigma, {s.count}, host::DType::F32, "weights_forward", "sigma");
  Weights out;
  out.w = Tensor({s.count}, "sample weights");
  out.acc = Tensor({R}, "accumulated opacity");
  out.depth = Tensor({R}, "depth");
  launch_with_local("composite", "weights_forward", "", {size_t(R)}, {kGroup}, sigma, s.deltas, s.t, s.ray_offset,
                    s.ray_count, R, out.w, out.acc, out.depth);
  return out;
}

Tensor weights_backward(const Samples& s, const Tensor& sigma, const Tensor& dw, const Tensor& dacc,
                        const Tensor& ddepth) {
  const int R = static_cast<int>(check_ray_lists(s.ray_offset, s.ray_count, "weights_backward"));
  host::expect_shape(sigma, {s.count}, host::DType::F32, "weights_backward", "sigma");
  if (dw.defined()) host::expect_shape(dw, {s.count}, host::DType::F32, "weights_backward", "dw");
  if (dacc.defined()) host::expect_shape(dacc, {R}, host::DType::F32, "weights_backward", "dacc");
  if (ddepth.defined()) host::expect_shape(ddepth, {R}, host::DType::F32, "weights_backward", "ddepth");
  auto opt = [](const Tensor& t) -> const Tensor& { return t.defined() ? t : absent(); };
  Tensor dsigma({s.count}, "dsigma");
  launch_with_local("composite", "weights_backward", "", {size_t(R)}, {kGroup}, sigma, s.deltas, s.t, s.ray_offset,
                    s.ray_count, R, opt(dw), int(dw.defined()), opt(dacc), int(dacc.defined()), opt(ddepth),
                    int(ddepth.defined()), dsigma);
  return dsigma;
}

}  // namespace stylerf::render
