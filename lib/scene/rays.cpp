#include "lib/scene/rays.hpp"

#include <cmath>

#include "host/error.hpp"

namespace stylerf::scene {

void pixel_ray(const Camera& cam, float px, float py, float o[3], float d[3]) {
  const float dc[3] = {(px - cam.cx) / cam.fx, -(py - cam.cy) / cam.fy, -1.0f};
  float n2 = 0;
  for (int r = 0; r < 3; ++r) {
    d[r] = cam.c2w[r][0] * dc[0] + cam.c2w[r][1] * dc[1] + cam.c2w[r][2] * dc[2];
    o[r] = cam.c2w[r][3];
    n2 += d[r] * d[r];
  }
  const float inv = 1.0f / std::sqrt(n2);
  for (int r = 0; r < 3; ++r) d[r] *= inv;
}

void to_ndc(const Camera& cam, float near, float o[3], float d[3]) {
  // Move the origin to the near plane first, so t = 0 is the near plane.
  const float t = -(near + o[2]) / d[2];
  float ox = o[0] + t * d[0], oy = o[1] + t * d[1], oz = o[2] + t * d[2];
  const float ax = -2.0f * cam.fx / cam.width, ay = -2.0f * cam.fy / cam.height;
  o[0] = ax * ox / oz;
  o[1] = ay * oy / oz;
  o[2] = 1.0f + 2.0f * near / oz;
  const float dx = ax * (d[0] / d[2] - ox / oz), dy = ay * (d[1] / d[2] - oy / oz), dz = -2.0f * near / oz;
  d[0] = dx;
  d[1] = dy;
  d[2] = dz;
}

std::array<float, 3> ndc_point(const Camera& cam, float near, const std::array<float, 3>& p) {
  const float ax = -2.0f * cam.fx / cam.width, ay = -2.0f * cam.fy / cam.height;
  return {ax * p[0] / p[2], ay * p[1] / p[2], 1.0f + 2.0f * near / p[2]};
}

namespace {
void emit(const Scene& scene, const Camera& cam, int x, int y, float* o, float* d) {
  pixel_ray(cam, x + 0.5f, y + 0.5f, o, d);
  if (scene.effects.ndc) to_ndc(cam, scene.ndc_near, o, d);
}
}  // namespace

Rays camera_rays(const Scene& scene, const Camera& cam) {
  Rays r;
  const size_t n = size_t(cam.width) * cam.height;
  r.origins.resize(3 * n);
  r.directions.resize(3 * n);
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      const size_t i = size_t(y) * cam.width + x;
      emit(scene, cam, x, y, &r.origins[3 * i], &r.directions[3 * i]);
    }
  return r;
}

RaySampler::RaySampler(const Scene& scene, uint64_t seed) : scene_(&scene), rng_(seed) {
  if (scene.train.empty()) throw host::Error("RaySampler: scene " + scene.name + " has no training views");
  per_view_ = size_t(scene.width()) * scene.height();
  total_ = per_view_ * scene.train.size();
  for (const View& v : scene.train)
    if (v.rgb.size() != 3 * per_view_)
      throw host::Error("RaySampler: view " + v.image_path + " has no image loaded or a different size");
}

Rays RaySampler::next(int batch) {
  Rays r;
  r.origins.resize(3 * size_t(batch));
  r.directions.resize(3 * size_t(batch));
  r.rgb.resize(3 * size_t(batch));
  r.pixel.resize(batch);
  std::uniform_int_distribution<size_t> pick(0, total_ - 1);
  const int w = scene_->width();
  for (int b = 0; b < batch; ++b) {
    const size_t p = pick(rng_);
    const View& v = scene_->train[p / per_view_];
    const size_t local = p % per_view_;
    const int x = int(local % w), y = int(local / w);
    emit(*scene_, v.camera, x, y, &r.origins[3 * size_t(b)], &r.directions[3 * size_t(b)]);
    for (int c = 0; c < 3; ++c) r.rgb[3 * size_t(b) + c] = v.rgb[3 * local + c];
    r.pixel[b] = int(p);
  }
  return r;
}

Rays slice(Rays all, size_t begin, size_t n) {
  if (begin + n > all.size())
    throw host::Error("rays: slice [" + std::to_string(begin) + ", " + std::to_string(begin + n) + ") of a batch of " +
                      std::to_string(all.size()));
  if (begin == 0 && n == all.size()) return all;
  auto part = [&](std::vector<float>& v, size_t width) {
    if (!v.empty()) v = std::vector<float>(v.begin() + long(begin * width), v.begin() + long((begin + n) * width));
  };
  part(all.origins, 3);
  part(all.directions, 3);
  part(all.rgb, 3);
  if (!all.pixel.empty())
    all.pixel = std::vector<int>(all.pixel.begin() + long(begin), all.pixel.begin() + long(begin + n));
  return all;
}

}  // namespace stylerf::scene
