// Merging the kept samples of a group of rays slab by slab: the index behind render_ray_groups
// (lib/model/ray_pipeline.hpp), multisample anti-aliasing's split for volumes. A group's rays (the sub-rays
// of one pixel footprint) share their origin's distance scale, and a march places every sample at t = a
// whole number of march steps from where its ray starts, so samples of different sub-rays with the same
// round(t / step) lie side by side across the footprint in one depth slab (step: the march step, or a
// multiple of it to merge along each ray too). Each such set becomes one merged point: its attributes the
// weight-averaged attributes of its members, its weight their summed weight over the group's size.
// Compositing a value linear in the attributes over the merged points gives exactly the mean over the
// group of each sub-ray's composite; a nonlinear value is evaluated once per slab of the footprint instead
// of once per sub-ray sample.
// Host code: the inputs are one int and two floats a kept sample (a few MB a call); the outputs are index
// lists that composite_values_forward (its indexed form, a tested device op) turns into merged attributes.
#pragma once
#include <cstdint>
#include <vector>

namespace stylerf::render {

struct StepMerge {
  // Kept-sample indices ordered by merged point, and each one's share of its point's weight (w / sum w).
  std::vector<int32_t> order;
  std::vector<float> share;
  // Per merged point: its members' range in `order`, and its weight (sum w of the members / group).
  std::vector<int32_t> point_offset, point_count;
  std::vector<float> point_weight;
  // Per group: its merged points' range (consecutive, in increasing step).
  std::vector<int32_t> group_offset, group_count;
  int64_t points() const { return int64_t(point_weight.size()); }
};

// ray_index, t, w: per kept sample (the kept list of a march: each ray's samples consecutive, in increasing
// t, rays in increasing order). rays: the rays of the call, a multiple of group; group g holds rays
// [g * group, (g + 1) * group). step > 0: the march's step in t. Samples with w = 0 still count (a point of
// zero weight shades nothing). Throws on a list out of order or a ray index out of range.
StepMerge merge_group_steps(const std::vector<int32_t>& ray_index, const std::vector<float>& t,
                            const std::vector<float>& w, int64_t rays, int group, float step);

}  // namespace stylerf::render
