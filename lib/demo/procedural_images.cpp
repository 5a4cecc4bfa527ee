#include "lib/demo/procedural_images.hpp"

#include <algorithm>
#include <cmath>

#include "lib/scene/analytic_scene.hpp"

namespace stylerf::demo {
namespace {

struct V3 {
  float x, y, z;
};
V3 operator+(V3 a, V3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
V3 operator-(V3 a, V3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
V3 operator*(V3 a, float s) { return {a.x * s, a.y * s, a.z * s}; }
V3 mul(V3 a, V3 b) { return {a.x * b.x, a.y * b.y, a.z * b.z}; }
float dot(V3 a, V3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
V3 cross(V3 a, V3 b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }
V3 normalize(V3 a) { return a * (1.0f / std::sqrt(dot(a, a))); }

float clamp01(float v) { return std::min(1.0f, std::max(0.0f, v)); }

}  // namespace

RgbImage render_content_image(int width, int height, float azimuth_degrees) {
  RgbImage img{width, height, std::vector<float>(3 * static_cast<size_t>(width) * height)};
  // The shapes, floor, Lambert shading and shadows are lib/scene's analytic tracer; this function only
  // adds the camera and a sky behind the scene.
  const scene::AnalyticScene world = scene::AnalyticScene::on_floor();
  const float az = azimuth_degrees * 3.14159265f / 180.0f;
  const V3 eye{5.0f * std::cos(az), 5.0f * std::sin(az), 2.6f}, target{0, 0, 0.6f};
  const V3 fwd = normalize(target - eye), right = normalize(cross(fwd, {0, 0, 1})), up = cross(right, fwd);
  const float tan_half = std::tan(0.5f * 45.0f * 3.14159265f / 180.0f), aspect = float(width) / height;
  const size_t plane = static_cast<size_t>(width) * height;
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      V3 col{0, 0, 0};
      // 2x2 supersampling: edges without staircase aliasing make a fairer content image.
      for (int s = 0; s < 4; ++s) {
        float u = (2.0f * (x + 0.25f + 0.5f * (s & 1)) / width - 1.0f) * tan_half * aspect;
        float v = (1.0f - 2.0f * (y + 0.25f + 0.5f * (s >> 1)) / height) * tan_half;
        V3 d = normalize(fwd + right * u + up * v);
        scene::SurfaceHit h = world.trace({eye.x, eye.y, eye.z}, {d.x, d.y, d.z});
        if (!h.hit) {
          float k = clamp01(0.5f + 0.5f * d.z);
          col = col + V3{0.55f + 0.3f * k, 0.7f + 0.2f * k, 0.95f};
          continue;
        }
        const auto c = world.shade(h);
        col = col + V3{c[0], c[1], c[2]};
      }
      col = col * 0.25f;
      size_t i = static_cast<size_t>(y) * width + x;
      img.data[i] = clamp01(col.x);
      img.data[plane + i] = clamp01(col.y);
      img.data[2 * plane + i] = clamp01(col.z);
    }
  return img;
}

RgbImage make_style_image(int width, int height, int variant) {
  RgbImage img{width, height, std::vector<float>(3 * static_cast<size_t>(width) * height)};
  const size_t plane = static_cast<size_t>(width) * height;
  // Palettes as cosine gradients a + b cos(2 pi (c t + d)).
  const V3 pa[2] = {{0.5f, 0.45f, 0.4f}, {0.55f, 0.5f, 0.45f}}, pb[2] = {{0.5f, 0.45f, 0.5f}, {0.45f, 0.5f, 0.5f}};
  const V3 pc[2] = {{1.0f, 1.0f, 1.0f}, {1.0f, 0.7f, 0.4f}}, pd[2] = {{0.0f, 0.15f, 0.55f}, {0.0f, 0.33f, 0.67f}};
  const int k = variant & 1;
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      float u = float(x) / width * 6.0f, v = float(y) / height * 6.0f;
      // Domain warp: swirls.
      float wu = u + 0.9f * std::sin(1.7f * v + 0.6f * std::sin(2.3f * u));
      float wv = v + 0.9f * std::cos(1.3f * u + 0.8f * std::sin(1.9f * v));
      float t = 0.5f + 0.25f * std::sin(2.0f * wu) + 0.25f * std::cos(2.5f * wv + variant);
      // Brush streaks: high-frequency stripes along the warped flow direction.
      float streak = 0.5f + 0.5f * std::sin(40.0f * (wu * 0.7f + wv * 0.3f));
      V3 c = pa[k] + mul(pb[k], V3{std::cos(6.2831853f * (pc[k].x * t + pd[k].x)),
                                   std::cos(6.2831853f * (pc[k].y * t + pd[k].y)),
                                   std::cos(6.2831853f * (pc[k].z * t + pd[k].z))});
      c = c * (0.7f + 0.3f * streak);
      size_t i = static_cast<size_t>(y) * width + x;
      img.data[i] = clamp01(c.x);
      img.data[plane + i] = clamp01(c.y);
      img.data[2 * plane + i] = clamp01(c.z);
    }
  return img;
}

}  // namespace stylerf::demo
