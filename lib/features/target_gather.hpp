// Reading the 1/4-resolution target maps (feature_targets.hpp) at full-resolution positions, on the device
// (kernels/targets.cl). Interpolation: bilinear at feature coordinate (px / 4 - 0.5, py / 4 - 0.5), clamped
// at the borders; pixel (x, y)'s centre is (x + 0.5, y + 0.5).
#pragma once
#include "host/tensor.hpp"
#include "lib/features/feature_targets.hpp"

namespace stylerf::features {

// maps [V, Hf, Wf, C] F32 or F16 (C a multiple of 8; F16 is read as float, the sums are float), view_index [R] I32, pixel_xy [R, 2] F32 full-resolution
// positions -> [R, C], the target of each ray. A view index outside [0, V) or a
// non-finite position gives a row of NaN (a bad input must not quietly read some other pixel).
host::Tensor gather_targets(const host::Tensor& maps, const host::Tensor& view_index, const host::Tensor& pixel_xy);

// dmaps [V, Hf, Wf, C] += the adjoint of gather_targets for the output gradient dout [R, C]. Training does
// not need it (targets are constants); it exists so the interpolation has a finite-difference test, and for
// splatting per-ray values onto a map. Atomic adds: the last bits depend on the order rays land.
// dmaps is F32.
void gather_targets_backward(const host::Tensor& view_index, const host::Tensor& pixel_xy, const host::Tensor& dout,
                             host::Tensor& dmaps);

// The targets under the full-resolution patch [x0, x0 + width) x [y0, y0 + height) of training view `view`, as
// [1, 256, height / scale, width / scale] (planar, like the decoder's feature maps): output pixel (i, j) is
// the target at the centre of its scale x scale block. scale 4 with x0, y0 multiples of 4 is an exact crop
// of the stored map (the fast profile, features rendered at 1/4); scale 1 gives per-pixel targets at full
// resolution (the paper profile). scale is 1, 2 or 4 and divides width and height; the patch lies inside the
// image. No backward: the targets are constants.
host::Tensor target_patch(const FeatureTargets& targets, int view, int x0, int y0, int width, int height, int scale);

}  // namespace stylerf::features
