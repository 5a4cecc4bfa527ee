#include "lib/render/ray_march.hpp"

#include <cmath>

#include "host/error.hpp"
#include "host/launch.hpp"
#include "lib/render/int_tensor.hpp"

namespace stylerf::render {

using host::Error;
using host::launch_with_local;

// Work-group size for per-ray and per-row kernels. Left to PoCL, a ray count like 4096 becomes two groups
// of 2048 (one per core: the slower core, or one descheduled by other load, sets the time) and an odd
// count like a sample total becomes groups of a few items (per-group overhead); 64 gives the pthread
// device many groups to balance. Global sizes are rounded up; the kernels guard their index.
constexpr size_t kGroup = 64;

float step_for_grid(const std::array<float, 3>& lo, const std::array<float, 3>& hi, const std::array<int, 3>& res,
                    float step_ratio) {
  double s = 0.0;
  for (int a = 0; a < 3; ++a) s += (hi[a] - lo[a]) / double(res[a] - 1);
  return static_cast<float>(s / 3.0 * step_ratio);
}

int max_samples_for_grid(const std::array<float, 3>& lo, const std::array<float, 3>& hi, float step) {
  double d2 = 0.0;
  for (int a = 0; a < 3; ++a) d2 += double(hi[a] - lo[a]) * (hi[a] - lo[a]);
  return static_cast<int>(std::sqrt(d2) / step) + 1;
}

// A one-byte stand-in for the mask argument when there is none.
static cl_mem no_mask() {
  static host::Buffer dummy(1, "no alpha mask");
  return dummy.mem();
}

Samples march(const Tensor& origins, const Tensor& dirs, const MarchConfig& cfg, const field::AlphaMask* mask) {
  if (origins.ndim() != 2 || origins.dim(1) != 3)
    throw Error("march: origins have shape " + host::shape_str(origins.shape()) + ", expected [R, 3]");
  host::expect_shape(dirs, origins.shape(), "march", "dirs");
  if (!(cfg.step > 0.0f)) throw Error("march: step must be positive");
  if (cfg.max_samples < 0) throw Error("march: max_samples must be >= 0");
  for (int a = 0; a < 3; ++a)
    if (!(cfg.box_hi[a] > cfg.box_lo[a])) throw Error("march: empty box along axis " + std::to_string(a));
  const int R = static_cast<int>(origins.dim(0));
  const bool has_mask = mask && mask->voxels;
  cl_mem mvox = has_mask ? mask->voxels->mem() : no_mask();
  const int mx = has_mask ? mask->res[0] : 1, my = has_mask ? mask->res[1] : 1, mz = has_mask ? mask->res[2] : 1;
  const auto& lo = cfg.box_lo;
  const auto& hi = cfg.box_hi;

  Samples s;
  Tensor counts({R}, "ray sample counts");
  launch_with_local("render", "march_count", "", {size_t(R)}, {kGroup}, origins, dirs, R, lo[0], lo[1], lo[2], hi[0], hi[1], hi[2], cfg.near,
         cfg.far, cfg.step, cfg.max_samples, int(cfg.jitter), int(cfg.seed), mvox, int(has_mask), mx, my, mz, counts);
  std::vector<int32_t> offsets;
  const std::vector<int32_t> hc = int_tensor_to_host(counts);
  s.count = exclusive_scan(hc, offsets);
  s.ray_count = counts;
  s.ray_offset = int_tensor_from_host(offsets, "ray sample offsets");
  const int64_t S = s.count;
  s.positions = Tensor({S, 3}, "sample positions");
  s.t = Tensor({S}, "sample t");
  s.deltas = Tensor({S}, "sample deltas");
  s.ray_index = Tensor({S}, "sample ray index");
  launch_with_local("render", "march_write", "", {size_t(R)}, {kGroup}, origins, dirs, R, lo[0], lo[1], lo[2], hi[0], hi[1], hi[2], cfg.near,
         cfg.far, cfg.step, cfg.max_samples, int(cfg.jitter), int(cfg.seed), mvox, int(has_mask), mx, my, mz,
         s.ray_offset, s.positions, s.t, s.deltas, s.ray_index, cfg.delta_scale);
  return s;
}

}  // namespace stylerf::render
