#include "lib/features/feature_sampler.hpp"

#include <algorithm>

#include "host/error.hpp"

namespace stylerf::features {

using host::Error;

host::Tensor FeatureRays::view_tensor() const {
  return host::Tensor::from_host(view, {int64_t(view.size())}, "ray view index");
}

host::Tensor FeatureRays::pixel_xy_tensor() const {
  return host::Tensor::from_host(pixel_xy, {int64_t(view.size()), 2}, "ray pixel_xy");
}

FeatureRaySampler::FeatureRaySampler(const scene::Scene& scene, uint64_t seed)
    : sampler_(scene, seed), width_(scene.width()), per_view_(size_t(scene.width()) * scene.height()) {}

FeatureRays FeatureRaySampler::next(int batch) {
  if (batch < 1) throw Error("FeatureRaySampler::next: batch must be at least 1, got " + std::to_string(batch));
  FeatureRays out;
  out.rays = sampler_.next(batch);
  out.view.resize(size_t(batch));
  out.pixel_xy.resize(2 * size_t(batch));
  for (int b = 0; b < batch; ++b) {
    // RaySampler's pixel index is view * (W * H) + y * W + x.
    const size_t p = size_t(out.rays.pixel[size_t(b)]);
    const size_t local = p % per_view_;
    out.view[size_t(b)] = int32_t(p / per_view_);
    out.pixel_xy[2 * size_t(b)] = float(local % size_t(width_)) + 0.5f;
    out.pixel_xy[2 * size_t(b) + 1] = float(local / size_t(width_)) + 0.5f;
  }
  return out;
}

host::Tensor Patch::rgb_tensor() const { return host::Tensor::from_host(rgb, {1, 3, height, width}, "patch rgb"); }

PatchSampler::PatchSampler(const scene::Scene& scene, uint64_t seed, int size) : scene_(&scene), rng_(seed) {
  if (scene.train.empty()) throw Error("PatchSampler: scene " + scene.name + " has no training views");
  if (size < 8 || size % 8)
    throw Error("PatchSampler: patch size " + std::to_string(size) + " must be a positive multiple of 8");
  const int w = scene.width(), h = scene.height();
  if (w < 8 || h < 8)
    throw Error("PatchSampler: scene " + scene.name + " has " + std::to_string(w) + "x" + std::to_string(h) +
                " images; a patch needs at least 8x8 pixels (VGG's three 2x2 poolings)");
  width_ = std::min(size, w / 8 * 8);
  height_ = std::min(size, h / 8 * 8);
  for (const scene::View& v : scene.train)
    if (v.camera.width != w || v.camera.height != h || v.rgb.size() != size_t(w) * h * 3)
      throw Error("PatchSampler: view " + v.image_path + " has no pixels loaded or another size than " +
                  std::to_string(w) + "x" + std::to_string(h));
}

FeatureRays slice(FeatureRays all, size_t begin, size_t n) {
  if (begin == 0 && n == all.size()) return all;
  all.rays = scene::slice(std::move(all.rays), begin, n);  // checks the range
  all.view = std::vector<int32_t>(all.view.begin() + long(begin), all.view.begin() + long(begin + n));
  all.pixel_xy = std::vector<float>(all.pixel_xy.begin() + long(2 * begin), all.pixel_xy.begin() + long(2 * (begin + n)));
  return all;
}

Patch PatchSampler::next(int stride) { return next(stride, rng_); }

Patch PatchSampler::next(int stride, std::mt19937_64& rng) const {
  const int W = scene_->width(), H = scene_->height();
  std::uniform_int_distribution<int> pick_view(0, int(scene_->train.size()) - 1);
  // Corners on the multiple-of-4 lattice that keep the patch inside the image.
  std::uniform_int_distribution<int> pick_x(0, (W - width_) / 4), pick_y(0, (H - height_) / 4);
  const int view = pick_view(rng);
  const int x0 = 4 * pick_x(rng);
  const int y0 = 4 * pick_y(rng);
  return at(view, x0, y0, stride);
}

Patch PatchSampler::at(int view, int x0, int y0, int stride) const {
  const int W = scene_->width(), H = scene_->height();
  if (view < 0 || view >= int(scene_->train.size()))
    throw Error("PatchSampler::at: view " + std::to_string(view) + " of " + std::to_string(scene_->train.size()));
  if (stride != 1 && stride != 2 && stride != 4)
    throw Error("PatchSampler: stride must be 1, 2 or 4, got " + std::to_string(stride));
  if (x0 < 0 || y0 < 0 || x0 % 4 || y0 % 4 || x0 + width_ > W || y0 + height_ > H)
    throw Error("PatchSampler::at: corner (" + std::to_string(x0) + ", " + std::to_string(y0) +
                ") must be a multiple of 4 with the " + std::to_string(width_) + "x" + std::to_string(height_) +
                " patch inside the " + std::to_string(W) + "x" + std::to_string(H) + " image");
  const scene::View& v = scene_->train[size_t(view)];
  Patch p;
  p.view = view;
  p.x0 = x0;
  p.y0 = y0;
  p.width = width_;
  p.height = height_;
  p.stride = stride;
  p.rgb.resize(size_t(3) * width_ * height_);
  for (int y = 0; y < height_; ++y)
    for (int x = 0; x < width_; ++x)
      for (int c = 0; c < 3; ++c)
        p.rgb[(size_t(c) * height_ + y) * width_ + x] = v.rgb[(size_t(y0 + y) * W + x0 + x) * 3 + c];
  const int ho = height_ / stride, wo = width_ / stride;
  const size_t n = size_t(ho) * wo;
  p.rays.origins.resize(3 * n);
  p.rays.directions.resize(3 * n);
  if (stride == 1) p.rays.rgb.resize(3 * n);
  for (int i = 0; i < ho; ++i)
    for (int j = 0; j < wo; ++j) {
      const size_t r = size_t(i) * wo + j;
      float* o = &p.rays.origins[3 * r];
      float* d = &p.rays.directions[3 * r];
      // The centre of the block: pixel centre (x + 0.5) for stride 1, the 4x4 block's (4j + 2) for stride 4.
      scene::pixel_ray(v.camera, x0 + stride * (j + 0.5f), y0 + stride * (i + 0.5f), o, d);
      if (scene_->effects.ndc) scene::to_ndc(v.camera, scene_->ndc_near, o, d);
      if (stride == 1)
        for (int c = 0; c < 3; ++c) p.rays.rgb[3 * r + size_t(c)] = v.rgb[(size_t(y0 + i) * W + x0 + j) * 3 + c];
    }
  return p;
}

}  // namespace stylerf::features
