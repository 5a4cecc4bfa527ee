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

void SceneStyleStats::attach(style::StyleCode& code) const {
  if (!m_->map_decoder->renormalises_relu4()) return;
  std::vector<double> sum, sq;
  std::vector<float> lo, hi;
  double count = 0;
  for (const auto& v : views_) {
    const Tensor r41 = m_->relu4_of(v.content, code, v.height, v.width);  // [1, C, h, w]
    const int64_t C = r41.dim(1), hw = r41.dim(2) * r41.dim(3);
    const auto x = r41.to_host();
    sum.resize(size_t(C), 0.0);
    sq.resize(size_t(C), 0.0);
    lo.resize(size_t(C), std::numeric_limits<float>::infinity());
    hi.resize(size_t(C), -std::numeric_limits<float>::infinity());
    for (int64_t c = 0; c < C; ++c)
      for (int64_t i = 0; i < hw; ++i) {
        const float v = x[size_t(c * hw + i)];
        const double val = v;
        sum[size_t(c)] += val;
        sq[size_t(c)] += val * val;
        lo[size_t(c)] = std::min(lo[size_t(c)], v);
        hi[size_t(c)] = std::max(hi[size_t(c)], v);
      }
    count += double(hw);
  }
  std::vector<float> mean(sum.size()), stdev(sum.size());
  for (size_t c = 0; c < sum.size(); ++c) {
    const double mu = sum[c] / count, var = std::max(0.0, sq[c] / count - mu * mu);
    mean[c] = float(mu);
    stdev[c] = float(std::sqrt(var + double(nn::kStatsEps)));
  }
  const int64_t C = int64_t(sum.size());
  code.scene_mean = Tensor::from_host(mean, {1, C}, "scene relu4_1 mean");
  code.scene_std = Tensor::from_host(stdev, {1, C}, "scene relu4_1 std");
  code.scene_lo = Tensor::from_host(lo, {1, C}, "scene relu4_1 min");
  code.scene_hi = Tensor::from_host(hi, {1, C}, "scene relu4_1 max");
}

}  // namespace stylerf::model
