#include "lib/render/distortion.hpp"

#include <cmath>
#include <string>

#include "host/error.hpp"
#include "host/launch.hpp"

namespace stylerf::render {

constexpr size_t kGroup = 64;  // per-ray kernels, as weights_forward

Distortion distortion_forward_backward(const Samples& s, const Tensor& w, float inv_len, float d, float scale) {
  const int R = static_cast<int>(check_ray_lists(s.ray_offset, s.ray_count, "distortion"));
  host::expect_shape(w, {s.count}, host::DType::F32, "distortion", "weights");
  host::expect_shape(s.t, {s.count}, host::DType::F32, "distortion", "t");
  if (!(inv_len > 0) || !std::isfinite(inv_len) || !(d >= 0) || !std::isfinite(d) || !std::isfinite(scale))
    throw host::Error("distortion: bad scales (inv_len " + std::to_string(inv_len) + ", d " + std::to_string(d) +
                      ", scale " + std::to_string(scale) + ")");
  Distortion out;
  out.loss = Tensor({R}, "distortion per ray");
  out.dw = Tensor({s.count}, "distortion dw");
  if (R == 0) return out;
  host::launch_with_local("composite", "distortion_forward_backward", "", {size_t(R)}, {kGroup}, w, s.t,
                          s.ray_offset, s.ray_count, R, inv_len, d, scale, out.loss, out.dw);
  return out;
}

}  // namespace stylerf::render
