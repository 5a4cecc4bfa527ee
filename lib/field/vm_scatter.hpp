// The VM grids' backward scatter: every sampled point adds its gradient into the grid elements its
// bilinear/linear taps read (see ScatterMode in vm_grid.hpp for the variants). Internal to lib/field:
// density_backward and features_backward call it after checking shapes.
#pragma once
#include <cstddef>

#include "lib/field/vm_grid.hpp"

namespace stylerf::field {

// Per-point kernels run in work-groups of 64: left to PoCL, a sample count such as 2735657 = 17*29*31*179
// gets an awkward divisor as its group size. The global size is rounded up; the kernels guard their index.
constexpr size_t kPointGroup = 64;

// dgrid += the scatter of dsrc at pts. kind 0: density (dsrc = dsigma [N], sigma [N], act); kind 1:
// features (dsrc = dfeat [N, features()], sigma unused).
void scatter_into_grid(const VMGrid& g, const Tensor& pts, const Tensor& dsrc, const Tensor& sigma, Tensor& dgrid,
                       int kind, DensityActivation act, ScatterMode mode);

}  // namespace stylerf::field
