#include "lib/model/scene_style_stats.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "host/error.hpp"
#include "lib/model/map_decoder.hpp"

namespace stylerf::model {

SceneStyleStats::SceneStyleStats(const StyleModel& m, const scene::Scene& scene, int views, int supersample,
                                 float refine_contrast)
    : m_(&m) {
  if (!m.map_decoder->renormalises_relu4()) return;
  if (scene.train.empty()) throw host::Error("scene style statistics: scene " + scene.root + " has no training views");
  const int n = int(scene.train.size()), k = std::max(1, std::min(views, n));
  for (int i = 0; i < k; ++i)
    views_.push_back(m.render_camera_content(scene, scene.train[size_t(int64_t(i) * n / k)].camera, 4096, nullptr,
                                             supersample != 0 ? supersample : m.inference_supersample,
                                             refine_contrast));
}

PooledRelu4Stats pool_relu4_stats(const std::vector<Tensor>& maps) {
  if (maps.empty()) throw host::Error("relu4_1 statistics: no maps to pool");
  const int64_t C = maps[0].dim(1);
  std::vector<double> sum(size_t(C), 0.0), sq(size_t(C), 0.0);
  std::vector<float> lo(size_t(C), std::numeric_limits<float>::infinity()),
      hi(size_t(C), -std::numeric_limits<float>::infinity());
  double count = 0;
  for (const Tensor& r41 : maps) {
    if (r41.dim(1) != C)
      throw host::Error("relu4_1 statistics: maps of " + std::to_string(C) + " and " + std::to_string(r41.dim(1)) +
                        " channels cannot be pooled");
    const int64_t n = r41.dim(0), hw = r41.dim(2) * r41.dim(3);
    const auto x = r41.to_host();
    for (int64_t i = 0; i < n; ++i)
      for (int64_t c = 0; c < C; ++c)
        for (int64_t k = 0; k < hw; ++k) {
          const float v = x[size_t((i * C + c) * hw + k)];
          sum[size_t(c)] += double(v);
          sq[size_t(c)] += double(v) * double(v);
          lo[size_t(c)] = std::min(lo[size_t(c)], v);
          hi[size_t(c)] = std::max(hi[size_t(c)], v);
        }
    count += double(n * hw);
  }
  std::vector<float> mean(static_cast<size_t>(C)), stdev(static_cast<size_t>(C));
  for (size_t c = 0; c < size_t(C); ++c) {
    const double mu = sum[c] / count, var = std::max(0.0, sq[c] / count - mu * mu);
    mean[c] = float(mu);
    stdev[c] = float(std::sqrt(var + double(nn::kStatsEps)));
  }
  return {Tensor::from_host(mean, {1, C}, "pooled relu4_1 mean"), Tensor::from_host(stdev, {1, C}, "pooled relu4_1 std"),
          Tensor::from_host(lo, {1, C}, "pooled relu4_1 min"), Tensor::from_host(hi, {1, C}, "pooled relu4_1 max")};
}

void SceneStyleStats::attach(style::StyleCode& code) const {
  if (!m_->map_decoder->renormalises_relu4()) return;
  std::vector<Tensor> maps;
  for (const auto& v : views_) maps.push_back(m_->relu4_of(v.content, code, v.height, v.width));  // [1, C, h, w]
  const PooledRelu4Stats s = pool_relu4_stats(maps);
  code.scene_mean = s.mean;
  code.scene_std = s.std;
  code.scene_lo = s.lo;
  code.scene_hi = s.hi;
}

}  // namespace stylerf::model
