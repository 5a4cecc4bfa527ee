// The background shell (kernels/background_shell.cl): for captures whose photos show real surroundings, a
// ray's background is a latitude-longitude map [H * W, C] read where the ray leaves a sphere of radius
// `radius` about the scene's centre, composited behind the ray as (1 - acc) * map(p). The taps (four texels
// and bilinear weights per ray) depend only on the rays, so a step computes them once and the forward and
// backward share them.
#pragma once
#include "host/tensor.hpp"

namespace stylerf::render {

using host::Tensor;

struct ShellTaps {
  Tensor idx;  // [R, 4] I32: texel rows of the map
  Tensor w;    // [R, 4] F32: bilinear weights, summing to 1
  int64_t rays() const { return idx.defined() ? idx.dim(0) : 0; }
};

// origins, dirs [R, 3] (dirs need not be unit); the map is height x width texels.
ShellTaps background_shell_taps(const Tensor& origins, const Tensor& dirs, float radius, int height, int width);

// value [R, C] += (1 - acc [R]) * bilinear(map [H * W, C]) at each ray's taps, in place.
void background_shell_forward(Tensor& value, const Tensor& acc, const Tensor& map, const ShellTaps& taps);

// The gradients of that term for dvalue [R, C]: w.r.t. acc, -<dvalue_r, bg_r>, written to *dacc or added
// to it when accumulate (dacc null: not wanted); w.r.t. the map, added to *dmap [H * W, C] (null: not
// wanted). The map's gradient sums each texel's taps in one work-item (grouped on the host): no atomics.
void background_shell_backward(const Tensor& dvalue, const Tensor& acc, const Tensor& map, const ShellTaps& taps,
                               Tensor* dacc, bool accumulate, Tensor* dmap);

}  // namespace stylerf::render
