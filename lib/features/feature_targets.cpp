#include "lib/features/feature_targets.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <ostream>

#include "host/error.hpp"
#include "host/half.hpp"

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

host::Shape target_shape(int views, int image_width, int image_height) {
  return {views, target_map_size(image_height), target_map_size(image_width), kTargetChannels};
}

FeatureTargets allocate_targets(int views, int image_width, int image_height, host::DType dtype) {
  if (dtype != host::DType::F16 && dtype != host::DType::F32)
    throw Error(std::string("feature targets: maps are stored as f16 or f32, not ") + host::dtype_name(dtype));
  if (views < 1 || image_width < 1 || image_height < 1)
    throw Error("feature targets: " + std::to_string(views) + " views of " + std::to_string(image_width) + "x" +
                std::to_string(image_height) + " pixels: nothing to store");
  FeatureTargets t;
  t.image_width = image_width;
  t.image_height = image_height;
  t.maps = host::Tensor(target_shape(views, image_width, image_height), dtype, "feature targets");
  return t;
}

size_t view_bytes(const FeatureTargets& t) { return t.views() ? t.maps.bytes() / size_t(t.views()) : 0; }

std::vector<uint8_t> encode_view(const std::vector<float>& hwc, host::DType dtype) {
  std::vector<uint8_t> out(hwc.size() * host::dtype_size(dtype));
  if (dtype == host::DType::F16)
    host::floats_to_halves(hwc.data(), hwc.size(), reinterpret_cast<uint16_t*>(out.data()));
  else if (dtype == host::DType::F32)
    std::memcpy(out.data(), hwc.data(), out.size());
  else
    throw Error(std::string("feature targets: maps are stored as f16 or f32, not ") + host::dtype_name(dtype));
  return out;
}

std::vector<float> maps_to_host(const FeatureTargets& t) {
  if (t.maps.dtype() == host::DType::F32) return t.maps.to_host();
  std::vector<uint16_t> bits(size_t(t.maps.numel()));
  t.maps.read_bytes(0, bits.data(), t.maps.bytes());
  std::vector<float> out(bits.size());
  host::halves_to_floats(bits.data(), bits.size(), out.data());
  return out;
}

void put_view(FeatureTargets& t, int view, const std::vector<uint8_t>& bytes) {
  const size_t n = view_bytes(t);
  if (view < 0 || view >= t.views() || bytes.size() != n)
    throw Error("feature targets: view " + std::to_string(view) + " of " + std::to_string(t.views()) + " given " +
                std::to_string(bytes.size()) + " bytes, expected " + std::to_string(n));
  t.maps.write_bytes(size_t(view) * n, bytes.data(), n);
}

FeatureTargets compute_scene_targets(const scene::Scene& scene, nn::VggEncoder& vgg, host::DType dtype,
                                     std::ostream* log,
                                     const std::function<void(const std::vector<uint8_t>&)>& each_view) {
  if (scene.train.empty()) throw Error("feature targets: scene " + scene.name + " has no training views");
  const int w = scene.width(), h = scene.height();
  const size_t V = scene.train.size();
  for (const scene::View& v : scene.train) {
    if (v.camera.width != w || v.camera.height != h)
      throw Error("feature targets: view " + v.image_path + " is " + std::to_string(v.camera.width) + "x" +
                  std::to_string(v.camera.height) + ", the first training view " + std::to_string(w) + "x" +
                  std::to_string(h) + " (all views must share one size)");
    if (v.rgb.size() != size_t(w) * h * 3)
      throw Error("feature targets: view " + v.image_path + " has no pixels loaded (load the scene with images)");
  }
  FeatureTargets all = allocate_targets(int(V), w, h, dtype);
  using clock = std::chrono::steady_clock;
  const auto t0 = clock::now();
  auto last = t0;
  auto seconds = [](clock::duration d) { return std::chrono::duration<double>(d).count(); };
  for (size_t i = 0; i < V; ++i) {
    const std::vector<uint8_t> bytes = encode_view(compute_view_targets(vgg, scene.train[i].rgb, h, w), dtype);
    put_view(all, int(i), bytes);
    if (each_view) each_view(bytes);
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
