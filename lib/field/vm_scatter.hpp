// The VM grids' backward scatter: every sampled point adds its gradient into the grid elements its
// bilinear/linear taps read (see ScatterMode in vm_grid.hpp for the variants). Internal to lib/field:
// density_backward and features_backward call it after checking shapes.
#pragma once
#include "lib/field/vm_grid.hpp"

namespace stylerf::field {

// dgrid += the scatter of dsrc at pts. kind 0: density (dsrc = dsigma [N], sigma [N], act); kind 1:
// features (dsrc = dfeat [N, features()], sigma unused).
void scatter_into_grid(const VMGrid& g, const Tensor& pts, const Tensor& dsrc, const Tensor& sigma, Tensor& dgrid,
                       int kind, DensityActivation act, ScatterMode mode);

}  // namespace stylerf::field
