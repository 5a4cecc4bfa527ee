#include "lib/demo/procedural_images.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>

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

namespace {

// splitmix64: a tiny, well-mixed, portable generator, so a variant's image is the same on every machine.
struct Rng {
  uint64_t s;
  uint64_t next() {
    uint64_t z = (s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  float uniform(float lo = 0, float hi = 1) { return lo + (hi - lo) * float(next() >> 40) / float(1 << 24); }
};

V3 hsv(float h, float s, float v) {
  h = h - std::floor(h);
  auto f = [&](float n) {
    const float k = std::fmod(n + h * 6.0f, 6.0f);
    return v - v * s * std::max(0.0f, std::min({k, 4.0f - k, 1.0f}));
  };
  return {f(5), f(3), f(1)};
}

// Piecewise-linear through the palette's colours, t in [0, 1].
V3 palette_at(const std::vector<V3>& pal, float t) {
  t = clamp01(t) * float(pal.size() - 1);
  const int i = std::min(int(pal.size()) - 2, int(t));
  const float f = t - float(i);
  return pal[size_t(i)] * (1 - f) + pal[size_t(i) + 1] * f;
}

float fract(float v) { return v - std::floor(v); }

// Value in [0, 1] of texture `kind` at (u, v) in [0, 1)^2: what the palette then colours.
struct Texture {
  int kind;
  float freq, angle, warp;
  std::vector<std::array<float, 2>> seeds;  // cell centres (stained glass)

  float operator()(float u, float v) const {
    const float ca = std::cos(angle), sa = std::sin(angle);
    const float a = (u * ca + v * sa) * freq, b = (-u * sa + v * ca) * freq;
    const float wa = a + warp * std::sin(1.7f * b + 0.6f * std::sin(2.3f * a));
    const float wb = b + warp * std::cos(1.3f * a + 0.8f * std::sin(1.9f * b));
    switch (kind) {
      case 0: {  // swirled brush streaks
        const float t = 0.5f + 0.25f * std::sin(2.0f * wa) + 0.25f * std::cos(2.5f * wb);
        return clamp01(t * (0.75f + 0.25f * std::sin(30.0f * (0.7f * wa + 0.3f * wb))));
      }
      case 1:  // wavy stripes, hard-edged
        return fract(0.5f * wa / 3.14159265f) < 0.5f ? 0.15f + 0.1f * std::sin(7 * wb) : 0.85f;
      case 2: {  // dots on a ground
        const float du = fract(a) - 0.5f, dv = fract(b + 0.5f * std::floor(a)) - 0.5f;
        const float r = std::sqrt(du * du + dv * dv);
        return r < 0.3f ? 0.9f - r : 0.1f + 0.2f * fract(std::floor(a) * 0.37f + std::floor(b) * 0.61f);
      }
      case 3: {  // stained glass: nearest of the cell centres, dark leading at the borders
        float d1 = 1e9f, d2 = 1e9f;
        size_t best = 0;
        for (size_t i = 0; i < seeds.size(); ++i) {
          const float dx = u - seeds[i][0], dy = v - seeds[i][1], d = dx * dx + dy * dy;
          if (d < d1) d2 = d1, d1 = d, best = i;
          else if (d < d2) d2 = d;
        }
        return std::sqrt(d2) - std::sqrt(d1) < 0.012f ? 0.0f : 0.2f + 0.8f * fract(float(best) * 0.618034f);
      }
      case 4: {  // cross-hatching: two sets of thin strokes
        const float h1 = std::abs(std::sin(3.0f * wa)), h2 = std::abs(std::sin(3.0f * (wa - wb)));
        return clamp01(0.95f - 0.6f * (h1 < 0.25f) - 0.4f * (h2 < 0.2f));
      }
      case 5:  // ripples around a centre
        return 0.5f + 0.5f * std::sin(2.5f * freq * std::sqrt((u - 0.4f) * (u - 0.4f) + (v - 0.6f) * (v - 0.6f)) * 6.0f +
                                      warp * std::sin(3 * wa));
      default: {  // mosaic: square tiles, one palette value each, with grout
        const float fa = fract(a), fb = fract(b);
        if (fa < 0.08f || fb < 0.08f) return 0.05f;
        return 0.15f + 0.85f * fract(std::sin(std::floor(a) * 12.9898f + std::floor(b) * 78.233f) * 43758.547f);
      }
    }
  }
};

}  // namespace

RgbImage make_varied_style_image(int width, int height, int variant) {
  Rng rng{0x5eed0000ull + uint64_t(uint32_t(variant)) * 7919ull};
  rng.next();
  // Palette: 3 or 4 colours around a base hue.
  const float hue = rng.uniform(), scheme = rng.uniform();
  const float spread = scheme < 0.33f ? 0.08f : scheme < 0.66f ? 0.5f : 0.333f;  // analogous / complementary / triadic
  const int n = rng.uniform() < 0.5f ? 3 : 4;
  std::vector<V3> pal;
  for (int i = 0; i < n; ++i) {
    const float h = hue + spread * float(i) + rng.uniform(-0.04f, 0.04f);
    pal.push_back(hsv(h, rng.uniform(0.45f, 1.0f), rng.uniform(0.25f, 1.0f)));
  }
  if (rng.uniform() < 0.5f) std::swap(pal.front(), pal.back());
  Texture tex;
  tex.kind = variant % 7;
  tex.freq = rng.uniform(3.0f, 9.0f);
  tex.angle = rng.uniform(0.0f, 3.14159265f);
  tex.warp = rng.uniform(0.2f, 1.2f);
  for (int i = 0; i < 24; ++i) tex.seeds.push_back({rng.uniform(), rng.uniform()});
  RgbImage img{width, height, std::vector<float>(3 * static_cast<size_t>(width) * height)};
  const size_t plane = static_cast<size_t>(width) * height;
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      const V3 c = palette_at(pal, tex(float(x) / float(width), float(y) / float(height)));
      const size_t i = static_cast<size_t>(y) * width + x;
      img.data[i] = clamp01(c.x);
      img.data[plane + i] = clamp01(c.y);
      img.data[2 * plane + i] = clamp01(c.z);
    }
  return img;
}

}  // namespace stylerf::demo
