#include "lib/render/ray_march.hpp"

#include <cmath>
#include <string>

#include "host/error.hpp"
#include "host/launch.hpp"
#include "lib/render/scan.hpp"

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

int64_t check_ray_lists(const Tensor& ray_offset, const Tensor& ray_count, const char* op) {
  host::expect_dtype(ray_count, host::DType::I32, op, "ray_count");
  if (ray_count.ndim() != 1)
    throw Error(std::string(op) + ": ray_count has shape " + host::shape_str(ray_count.shape()) + ", expected [R]");
  host::expect_shape(ray_offset, ray_count.shape(), host::DType::I32, op, "ray_offset");
  return ray_count.numel();
}

// A one-byte stand-in for the mask argument when there is none.
static const Tensor& no_mask() {
  static Tensor dummy = Tensor::zeros({1, 1, 1}, host::DType::U8, "no alpha mask");
  return dummy;
}

Samples march(const Tensor& origins, const Tensor& dirs, const MarchConfig& cfg, const field::AlphaMask* mask,
              const DensityMarch* density) {
  host::expect_dtype(origins, host::DType::F32, "march", "origins");
  if (origins.ndim() != 2 || origins.dim(1) != 3)
    throw Error("march: origins have shape " + host::shape_str(origins.shape()) + ", expected [R, 3]");
  host::expect_shape(dirs, origins.shape(), host::DType::F32, "march", "dirs");
  if (!(cfg.step > 0.0f)) throw Error("march: step must be positive");
  if (cfg.max_samples < 0) throw Error("march: max_samples must be >= 0");
  for (int a = 0; a < 3; ++a)
    if (!(cfg.box_hi[a] > cfg.box_lo[a])) throw Error("march: empty box along axis " + std::to_string(a));
  const int R = static_cast<int>(origins.dim(0));
  const bool has_mask = mask && mask->voxels.defined();
  if (has_mask)
    host::expect_shape(mask->voxels, {mask->res[2], mask->res[1], mask->res[0]}, host::DType::U8, "march",
                       "alpha mask voxels");
  const Tensor& mvox = has_mask ? mask->voxels : no_mask();
  const int mx = has_mask ? mask->res[0] : 1, my = has_mask ? mask->res[1] : 1, mz = has_mask ? mask->res[2] : 1;
  const auto& lo = cfg.box_lo;
  const auto& hi = cfg.box_hi;

  if (density) {
    if (!density->grid || !density->grid->params.defined()) throw Error("march: early termination without a density grid");
    if (!(density->ert_threshold > 0.0f && density->ert_threshold < 1.0f))
      throw Error("march: early-termination threshold " + std::to_string(density->ert_threshold) + " is not in (0, 1)");
  }

  Samples s;
  Tensor counts({R}, host::DType::I32, "ray sample counts");
  Tensor staged;  // early termination: [R, cap] sigma of each ray's samples, before compaction
  const int cap = cfg.max_samples;
  if (density) {
    const field::VMGrid& g = *density->grid;
    staged = Tensor({int64_t(R) * std::max(cap, 1)}, "staged sample density");
    launch_with_local("grid+render+march_density", "march_density_count", field::rank_build_options(g.rank),
                      {size_t(R)}, {kGroup}, origins, dirs, R, lo[0], lo[1], lo[2], hi[0], hi[1], hi[2], cfg.near,
                      cfg.far, cfg.step, cfg.max_samples, int(cfg.jitter), int(cfg.seed), cfg.ray_base, mvox, int(has_mask), mx,
                      my, mz, g.params, g.res[0], g.res[1], g.res[2], g.rank[0], g.rank[1], g.rank[2], int(density->act),
                      cfg.delta_scale, density->ert_threshold, std::max(cap, 1), staged, counts);
  } else {
    launch_with_local("render", "march_count", "", {size_t(R)}, {kGroup}, origins, dirs, R, lo[0], lo[1], lo[2], hi[0], hi[1], hi[2], cfg.near,
           cfg.far, cfg.step, cfg.max_samples, int(cfg.jitter), int(cfg.seed), cfg.ray_base, mvox, int(has_mask), mx, my, mz, counts);
  }
  std::vector<int32_t> offsets;
  s.count = exclusive_scan(counts.to_host_i32(), offsets);
  s.ray_count = counts;
  s.ray_offset = Tensor::from_host(offsets, {R}, "ray sample offsets");
  const int64_t S = s.count;
  s.positions = Tensor({S, 3}, "sample positions");
  s.t = Tensor({S}, "sample t");
  s.deltas = Tensor({S}, "sample deltas");
  s.ray_index = Tensor({S}, host::DType::I32, "sample ray index");
  launch_with_local("render", "march_write", "", {size_t(R)}, {kGroup}, origins, dirs, R, lo[0], lo[1], lo[2], hi[0], hi[1], hi[2], cfg.near,
         cfg.far, cfg.step, cfg.max_samples, int(cfg.jitter), int(cfg.seed), cfg.ray_base, mvox, int(has_mask), mx, my, mz,
         s.ray_offset, counts, s.positions, s.t, s.deltas, s.ray_index, cfg.delta_scale);
  if (density) {
    s.sigma = Tensor({S}, "density");
    launch_with_local("grid+render+march_density", "stage_compact", field::rank_build_options(density->grid->rank),
                      {size_t(R)}, {kGroup}, staged, s.ray_offset, counts, R, std::max(cap, 1), s.sigma);
  }
  return s;
}

}  // namespace stylerf::render
