#include "lib/render/step_merge.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

#include "host/error.hpp"

namespace stylerf::render {

using host::Error;

StepMerge merge_group_steps(const std::vector<int32_t>& ray_index, const std::vector<float>& t,
                            const std::vector<float>& w, int64_t rays, int group, float step) {
  const size_t K = ray_index.size();
  if (t.size() != K || w.size() != K)
    throw Error("merge_group_steps: " + std::to_string(K) + " ray indices but " + std::to_string(t.size()) + " t and " +
                std::to_string(w.size()) + " weights");
  if (group < 1) throw Error("merge_group_steps: group must be >= 1, got " + std::to_string(group));
  if (rays % group != 0)
    throw Error("merge_group_steps: " + std::to_string(rays) + " rays are not whole groups of " + std::to_string(group));
  if (!(step > 0.0f) || !std::isfinite(step)) throw Error("merge_group_steps: step must be finite and > 0");
  const int64_t groups = rays / group;
  StepMerge m;
  m.order.reserve(K);
  m.share.reserve(K);
  m.group_offset.assign(size_t(groups), 0);
  m.group_count.assign(size_t(groups), 0);
  std::vector<std::pair<int64_t, int32_t>> keyed;  // (step number, kept index) of one group
  size_t k = 0;
  for (int64_t g = 0; g < groups; ++g) {
    keyed.clear();
    const int64_t last_ray = (g + 1) * group;
    for (; k < K && ray_index[k] < last_ray; ++k) {
      const bool back = k > 0 && (ray_index[k] < ray_index[k - 1] || (ray_index[k] == ray_index[k - 1] && !(t[k] > t[k - 1])));
      if (ray_index[k] < g * group || back)
        throw Error("merge_group_steps: kept sample " + std::to_string(k) + " (ray " + std::to_string(ray_index[k]) +
                    ") is out of order: the list must go ray by ray, in increasing t");
      keyed.emplace_back(std::llround(double(t[k]) / double(step)), int32_t(k));
    }
    // Stable: a ray's members stay in t order, and equal steps keep their rays' order.
    std::stable_sort(keyed.begin(), keyed.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    m.group_offset[size_t(g)] = int32_t(m.point_weight.size());
    for (size_t i = 0; i < keyed.size();) {
      size_t j = i;
      double sum = 0.0;
      for (; j < keyed.size() && keyed[j].first == keyed[i].first; ++j) sum += w[size_t(keyed[j].second)];
      m.point_offset.push_back(int32_t(m.order.size()));
      m.point_count.push_back(int32_t(j - i));
      m.point_weight.push_back(float(sum / group));
      for (size_t q = i; q < j; ++q) {
        const int32_t idx = keyed[q].second;
        m.order.push_back(idx);
        // Zero total weight: equal shares, so the merged attributes stay the members' plain mean.
        m.share.push_back(sum > 0.0 ? float(w[size_t(idx)] / sum) : 1.0f / float(j - i));
      }
      i = j;
    }
    m.group_count[size_t(g)] = int32_t(m.point_weight.size()) - m.group_offset[size_t(g)];
  }
  if (k != K)
    throw Error("merge_group_steps: kept sample " + std::to_string(k) + " has ray " + std::to_string(ray_index[k]) +
                ", outside the " + std::to_string(rays) + " rays (or the list is out of order)");
  return m;
}

}  // namespace stylerf::render
