#include "lib/features/target_gather.hpp"

#include <climits>

#include "host/error.hpp"
#include "host/launch.hpp"

namespace stylerf::features {

using host::Error;
using host::Tensor;

namespace {

// Per-ray kernels in groups of 64: PoCL would otherwise split 4096 rays into one group per core, and the
// slower (or busier) core would set the time.
constexpr size_t kGroup = 64;

struct MapDims {
  int V, hf, wf, C;
};

// The program options that read maps of this dtype (kernels/targets.cl: TARGETS_F16).
const char* map_options(const Tensor& maps) { return maps.dtype() == host::DType::F16 ? "-DTARGETS_F16" : ""; }

MapDims map_dims(const Tensor& maps, const char* op) {
  if (!maps.defined()) throw Error(std::string(op) + ": the target maps are undefined");
  if (maps.dtype() != host::DType::F16) host::expect_dtype(maps, host::DType::F32, op, "target maps (f32 or f16)");
  if (maps.ndim() != 4)
    throw Error(std::string(op) + ": target maps must be [V, Hf, Wf, C], got " + host::shape_str(maps.shape()));
  const MapDims d{int(maps.dim(0)), int(maps.dim(1)), int(maps.dim(2)), int(maps.dim(3))};
  if (d.V < 1 || d.hf < 1 || d.wf < 1 || d.C < 8 || d.C % 8)
    throw Error(std::string(op) + ": target maps " + host::shape_str(maps.shape()) +
                " need at least one view and pixel and a channel count that is a positive multiple of 8");
  return d;
}

int ray_count(const Tensor& view_index, const Tensor& pixel_xy, const char* op) {
  host::expect_dtype(view_index, host::DType::I32, op, "view_index");
  if (view_index.ndim() != 1)
    throw Error(std::string(op) + ": view_index must be [R], got " + host::shape_str(view_index.shape()));
  if (view_index.numel() > INT_MAX / 2) throw Error(std::string(op) + ": too many rays for int indexing");
  const int R = int(view_index.numel());
  host::expect_shape(pixel_xy, {R, 2}, host::DType::F32, op, "pixel_xy");
  return R;
}

}  // namespace

Tensor gather_targets(const Tensor& maps, const Tensor& view_index, const Tensor& pixel_xy) {
  const MapDims d = map_dims(maps, "gather_targets");
  const int R = ray_count(view_index, pixel_xy, "gather_targets");
  Tensor out({R, d.C}, "gathered targets");
  if (R == 0) return out;
  host::launch_with_local("targets", "targets_gather", map_options(maps), {size_t(R)}, {kGroup}, maps, view_index, pixel_xy, R, d.V,
                          d.hf, d.wf, d.C, out);
  return out;
}

void gather_targets_backward(const Tensor& view_index, const Tensor& pixel_xy, const Tensor& dout, Tensor& dmaps) {
  const MapDims d = map_dims(dmaps, "gather_targets_backward");
  host::expect_dtype(dmaps, host::DType::F32, "gather_targets_backward", "dmaps");  // float atomics
  const int R = ray_count(view_index, pixel_xy, "gather_targets_backward");
  host::expect_shape(dout, {R, d.C}, host::DType::F32, "gather_targets_backward", "dout");
  if (R == 0) return;
  host::launch_with_local("targets", "targets_gather_backward", "", {size_t(R)}, {kGroup}, view_index, pixel_xy, dout,
                          R, d.V, d.hf, d.wf, d.C, dmaps);
}

Tensor target_patch(const FeatureTargets& targets, int view, int x0, int y0, int width, int height, int scale) {
  const MapDims d = map_dims(targets.maps, "target_patch");
  auto fail = [&](const std::string& what) {
    throw Error("target_patch: patch " + std::to_string(width) + "x" + std::to_string(height) + " at (" +
                std::to_string(x0) + ", " + std::to_string(y0) + ") of view " + std::to_string(view) + ", scale " +
                std::to_string(scale) + ": " + what);
  };
  if (view < 0 || view >= d.V) fail("there are " + std::to_string(d.V) + " training views");
  if (scale != 1 && scale != 2 && scale != 4) fail("scale must be 1, 2 or 4");
  if (width <= 0 || height <= 0 || width % scale || height % scale) fail("the scale must divide a non-empty size");
  if (x0 < 0 || y0 < 0 || x0 + width > targets.image_width || y0 + height > targets.image_height)
    fail("it must lie inside the " + std::to_string(targets.image_width) + "x" + std::to_string(targets.image_height) +
         " image");
  const int ho = height / scale, wo = width / scale;
  Tensor out({1, d.C, ho, wo}, "target patch");
  host::launch_with_local("targets", "targets_patch", map_options(targets.maps), {size_t(ho) * wo}, {kGroup}, targets.maps, view, d.hf, d.wf,
                          d.C, x0, y0, scale, ho, wo, out);
  return out;
}

}  // namespace stylerf::features
