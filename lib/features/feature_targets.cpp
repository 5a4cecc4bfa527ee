#include "lib/features/feature_targets.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <ostream>

#include "host/error.hpp"

namespace stylerf::features {

using host::Error;

int target_map_size(int pixels) { return (pixels + kTargetStride - 1) / kTargetStride; }

int reflect_index(int i, int n) {
  if (n <= 0) throw Error("reflect_index: empty dimension");
  if (n == 1) return 0;
  const int period = 2 * (n - 1);
  int m = i % period;
  if (m < 0) m += period;
  return m < n ? m : period - m;
}

std::vector<float> pad_to_multiple_chw(const std::vector<float>& rgb, int h, int w, int multiple, int& ph, int& pw) {
  if (h <= 0 || w <= 0)
    throw Error("pad_to_multiple_chw: empty image (" + std::to_string(w) + "x" + std::to_string(h) + ")");
  if (rgb.size() != size_t(h) * w * 3)
    throw Error("pad_to_multiple_chw: " + std::to_string(rgb.size()) + " values for a " + std::to_string(w) + "x" +
                std::to_string(h) + " RGB image");
  ph = (h + multiple - 1) / multiple * multiple;
  pw = (w + multiple - 1) / multiple * multiple;
  std::vector<float> out(size_t(3) * ph * pw);
  for (int y = 0; y < ph; ++y) {
    const int sy = reflect_index(y, h);
    for (int x = 0; x < pw; ++x) {
      const int sx = reflect_index(x, w);
      for (int c = 0; c < 3; ++c) out[(size_t(c) * ph + y) * pw + x] = rgb[(size_t(sy) * w + sx) * 3 + c];
    }
  }
  return out;
}

std::vector<float> compute_view_targets(nn::VggEncoder& vgg, const std::vector<float>& rgb, int h, int w) {
  int ph = 0, pw = 0;
  // Multiples of 8: VggEncoder checks for the three poolings of relu4_1 even when it stops at relu3_1.
  const std::vector<float> padded = pad_to_multiple_chw(rgb, h, w, 8, ph, pw);
  const host::Tensor x = host::Tensor::from_host(padded, {1, 3, ph, pw}, "target image");
  const nn::VggFeatures f = vgg.forward(x, 3, /*keep_for_backward=*/false);
  const host::Tensor& r31 = f[2];
  const int mh = ph / kTargetStride, mw = pw / kTargetStride;
  host::expect_shape(r31, {1, kTargetChannels, mh, mw}, "compute_view_targets", "relu3_1");
  const std::vector<float> nchw = r31.to_host();
  const int hf = target_map_size(h), wf = target_map_size(w);
  std::vector<float> out(size_t(hf) * wf * kTargetChannels);
  for (int i = 0; i < hf; ++i)
    for (int j = 0; j < wf; ++j) {
      float* dst = &out[(size_t(i) * wf + j) * kTargetChannels];
      for (int c = 0; c < kTargetChannels; ++c) dst[c] = nchw[(size_t(c) * mh + i) * mw + j];
    }
  return out;
}

std::vector<float> compute_scene_targets(const scene::Scene& scene, nn::VggEncoder& vgg, std::ostream* log) {
  if (scene.train.empty()) throw Error("feature targets: scene " + scene.name + " has no training views");
  const int w = scene.width(), h = scene.height();
  const int hf = target_map_size(h), wf = target_map_size(w);
  const size_t per_view = size_t(hf) * wf * kTargetChannels;
  const size_t V = scene.train.size();
  for (const scene::View& v : scene.train) {
    if (v.camera.width != w || v.camera.height != h)
      throw Error("feature targets: view " + v.image_path + " is " + std::to_string(v.camera.width) + "x" +
                  std::to_string(v.camera.height) + ", the first training view " + std::to_string(w) + "x" +
                  std::to_string(h) + " (all views must share one size)");
    if (v.rgb.size() != size_t(w) * h * 3)
      throw Error("feature targets: view " + v.image_path + " has no pixels loaded (load the scene with images)");
  }
  std::vector<float> all(per_view * V);
  using clock = std::chrono::steady_clock;
  const auto t0 = clock::now();
  auto last = t0;
  auto seconds = [](clock::duration d) { return std::chrono::duration<double>(d).count(); };
  for (size_t i = 0; i < V; ++i) {
    const std::vector<float> one = compute_view_targets(vgg, scene.train[i].rgb, h, w);
    std::copy(one.begin(), one.end(), all.begin() + std::ptrdiff_t(per_view * i));
    const auto now = clock::now();
    if (log && (seconds(now - last) >= 2.0 || i + 1 == V)) {
      last = now;
      const double rate = double(i + 1) / std::max(seconds(now - t0), 1e-9);
      char line[160];
      std::snprintf(line, sizeof line, "feature targets: %zu/%zu views, %.2f views/s, %.0f s left", i + 1, V, rate,
                    double(V - i - 1) / rate);
      *log << line << std::endl;
    }
  }
  return all;
}

}  // namespace stylerf::features
