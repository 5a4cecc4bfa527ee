#include "lib/field/alpha_mask.hpp"

#include <algorithm>

#include "host/error.hpp"
#include "host/launch.hpp"

namespace stylerf::field {

using host::launch;

std::vector<uint8_t> AlphaMask::to_host() const {
  if (!voxels.defined()) return {};
  return voxels.to_host_u8();
}

AlphaMask build_alpha_mask(const VMGrid& density, DensityActivation act, std::array<int, 3> res, float step,
                           float threshold) {
  for (int a = 0; a < 3; ++a)
    if (res[a] < 1) throw host::Error("alpha mask: resolution must be positive");
  AlphaMask m;
  m.res = res;
  const size_t n = size_t(res[0]) * res[1] * res[2];
  const host::Shape shape{res[2], res[1], res[0]};
  host::Tensor raw(shape, host::DType::U8, "alpha mask (raw)");
  m.voxels = host::Tensor(shape, host::DType::U8, "alpha mask");
  const std::string opts = rank_build_options(density.rank);  // the build the grid kernels use
  // Groups of 64 voxels (an explicit size: PoCL picks awkward divisors of odd voxel counts).
  host::launch_with_local("grid", "alpha_mask_eval", opts, {n}, {64}, density.params, raw, int(res[0]), int(res[1]), int(res[2]),
         density.res[0], density.res[1], density.res[2], density.rank[0], density.rank[1], density.rank[2], int(act),
         step, threshold);
  launch("grid", "alpha_mask_dilate", {n}, raw, m.voxels, int(res[0]), int(res[1]), int(res[2]));
  // The tight box: read back once per rebuild (rare: on the trainer's schedule).
  const std::vector<uint8_t> v = m.to_host();
  int lo[3] = {res[0], res[1], res[2]}, hi[3] = {-1, -1, -1};
  for (int z = 0; z < res[2]; ++z)
    for (int y = 0; y < res[1]; ++y)
      for (int x = 0; x < res[0]; ++x)
        if (v[(size_t(z) * res[1] + y) * res[0] + x]) {
          ++m.occupied;
          const int c[3] = {x, y, z};
          for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], c[a]);
            hi[a] = std::max(hi[a], c[a]);
          }
        }
  if (m.occupied)
    for (int a = 0; a < 3; ++a) {
      m.lo[a] = -1.0f + 2.0f * lo[a] / res[a];
      m.hi[a] = -1.0f + 2.0f * (hi[a] + 1) / res[a];
    }
  return m;
}

}  // namespace stylerf::field
