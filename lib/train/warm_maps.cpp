#include "lib/train/warm_maps.hpp"

#include <algorithm>
#include <chrono>
#include <iomanip>
#include <ostream>
#include <sstream>

#include "host/error.hpp"

namespace stylerf::train {

using host::Error;
using host::Tensor;

const char* warm_maps_name(WarmMaps m) { return m == WarmMaps::Rendered ? "rendered" : "vgg"; }

WarmMaps parse_warm_maps(const std::string& name) {
  if (name == "vgg") return WarmMaps::Vgg;
  if (name == "rendered") return WarmMaps::Rendered;
  throw host::SettingError("warm_maps", "must be vgg or rendered, got '" + name + "'");
}

float RenderedWarmMaps::opacity(int view, int i, int j) const {
  const int h = maps.map_height(), w = maps.map_width();
  i = std::clamp(i, 0, h - 1);
  j = std::clamp(j, 0, w - 1);
  return acc[(size_t(view) * h + i) * w + j];
}

RenderedWarmMaps render_warm_maps(const model::FeatureModel& features, const scene::Scene& scene, std::ostream* log) {
  if (features.stride() != features::kTargetStride)
    throw Error("warm-start maps: rendered maps need the fast profile (one ray per " +
                std::to_string(features::kTargetStride) + "x" + std::to_string(features::kTargetStride) + " block)");
  if (scene.train.empty()) throw Error("warm-start maps: the scene has no training views");
  const int V = int(scene.train.size());
  const int64_t C = features.field.channels();
  if (C != features::kTargetChannels)
    throw Error("warm-start maps: the feature field has " + std::to_string(C) + " channels, the stylizer reads " +
                std::to_string(features::kTargetChannels));
  std::vector<float> bg(size_t(C), 0.0f);
  if (features.field.background.value.defined()) bg = features.field.background.value.to_host();
  const auto t0 = std::chrono::steady_clock::now();
  RenderedWarmMaps out;
  std::vector<float> view_map;  // one view [Hf][Wf][C]: the maps are filled a view at a time (native sizes)
  int Hf = 0, Wf = 0;
  double last_line_s = 0;
  for (int v = 0; v < V; ++v) {
    const scene::Camera& cam = scene.train[size_t(v)].camera;
    const model::FeatureModel::FeatureMap fm = features.render_feature_map(scene, cam);
    if (v == 0) {
      Hf = fm.height;
      Wf = fm.width;
      view_map.resize(size_t(Hf) * Wf * C);
      out.acc.resize(size_t(V) * Hf * Wf);
      out.maps = features::allocate_targets(V, scene.width(), scene.height());
      if (out.maps.map_height() != Hf || out.maps.map_width() != Wf)
        throw Error("warm-start maps: rendered maps are " + std::to_string(Wf) + "x" + std::to_string(Hf) +
                    ", the targets' layout " + std::to_string(out.maps.map_width()) + "x" +
                    std::to_string(out.maps.map_height()));
    } else if (fm.height != Hf || fm.width != Wf) {
      throw Error("warm-start maps: training view " + scene.train[size_t(v)].image_path + " is " +
                  std::to_string(cam.width) + "x" + std::to_string(cam.height) + ", unlike the first view");
    }
    const auto f = fm.features.to_host();  // [1, C, Hf, Wf]
    const int64_t n = int64_t(Hf) * Wf;
    // With a background shell, its term at each map pixel's ray ([n, C]), taken off as the colour's is.
    std::vector<float> shell;
    if (features.geo.shell.on()) {
      int w = 0, h = 0;
      const scene::Rays rays = model::block_rays(scene, cam, features.stride(), w, h);
      shell = features.field
                  .shell_term(features.geo, Tensor::from_host(rays.origins, {n, 3}), Tensor::from_host(rays.directions, {n, 3}),
                              Tensor::from_host(std::vector<float>(fm.acc.begin(), fm.acc.end()), {n}))
                  .to_host();
    }
    for (int64_t p = 0; p < n; ++p) {
      const float a = fm.acc[size_t(p)];
      out.acc[size_t(v * n + p)] = a;
      float* dst = &view_map[size_t(p * C)];
      if (!(a > kWarmMapMinOpacity)) {
        std::fill(dst, dst + C, 0.0f);
        continue;
      }
      // value = sum w f + (1 - acc) bg  ->  mean feature = (value - (1 - acc) bg) / acc
      for (int64_t c = 0; c < C; ++c)
        dst[c] = (f[size_t(c * n + p)] - (1.0f - a) * bg[size_t(c)] - (shell.empty() ? 0.0f : shell[size_t(p * C + c)])) / a;
    }
    features::put_view(out.maps, v, features::encode_view(view_map, out.maps.maps.dtype()));
    if (log) {
      // A line about every two seconds and at the end, as the other progress lines (a log file gets lines,
      // not carriage returns).
      const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      if (s - last_line_s >= 2.0 || v + 1 == V) {
        last_line_s = s;
        std::ostringstream line;  // formatted apart: the caller's stream keeps its own precision
        line << "  warm-start maps: rendered " << v + 1 << "/" << V << " training views (" << std::fixed
             << std::setprecision(1) << s << " s)";
        *log << line.str() << std::endl;
      }
    }
  }
  return out;
}

}  // namespace stylerf::train
