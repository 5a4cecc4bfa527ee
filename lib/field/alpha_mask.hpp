// The alpha mask: an occupancy grid over the scene box, built from the density grid, that lets ray
// marching skip empty space (TensoRF's alphaMask, updated on a schedule by the trainer).
//
// Voxel (x, y, z) of an [mz][my][mx] grid covers normalised coordinates [-1 + 2x/mx, -1 + 2(x+1)/mx] (etc.);
// it is occupied when alpha = 1 - exp(-sigma(centre) * step) > threshold, then dilated by one voxel
// (3x3x3 max, as TensoRF max-pools its alpha volume) so surfaces between voxel centres are kept.
#pragma once
#include <array>
#include <vector>

#include "host/tensor.hpp"
#include "lib/field/vm_grid.hpp"

namespace stylerf::field {

struct AlphaMask {
  std::array<int, 3> res{};               // mx, my, mz
  host::Tensor voxels;                    // U8 [mz, my, mx], 1 = occupied; undefined: no mask
  int64_t occupied = 0;                   // occupied voxels after dilation
  // Tight box of occupied voxels in normalised coordinates (lo > hi when nothing is occupied).
  std::array<float, 3> lo{1, 1, 1}, hi{-1, -1, -1};
  bool empty() const { return occupied == 0; }
  std::vector<uint8_t> to_host() const;
};

// step: the sample spacing in the units compositing uses (world step * distance scale).
AlphaMask build_alpha_mask(const VMGrid& density, DensityActivation act, std::array<int, 3> res, float step,
                           float threshold = 1e-4f);

}  // namespace stylerf::field
