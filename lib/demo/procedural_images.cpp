#include "lib/demo/procedural_images.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

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

struct Hit {
  float t = std::numeric_limits<float>::infinity();
  V3 normal{0, 0, 0};
  V3 albedo{0, 0, 0};
};

void hit_sphere(V3 o, V3 d, V3 c, float r, V3 albedo, Hit& h) {
  V3 oc = o - c;
  float b = dot(oc, d), cc = dot(oc, oc) - r * r, disc = b * b - cc;
  if (disc < 0) return;
  float t = -b - std::sqrt(disc);
  if (t > 1e-4f && t < h.t) {
    h.t = t;
    h.normal = normalize(o + d * t - c);
    h.albedo = albedo;
  }
}

void hit_box(V3 o, V3 d, V3 lo, V3 hi, V3 albedo, Hit& h) {
  float t0 = -std::numeric_limits<float>::infinity(), t1 = std::numeric_limits<float>::infinity();
  int axis = 0;
  float sign = 1;
  const float os[3] = {o.x, o.y, o.z}, ds[3] = {d.x, d.y, d.z}, los[3] = {lo.x, lo.y, lo.z}, his[3] = {hi.x, hi.y, hi.z};
  for (int a = 0; a < 3; ++a) {
    float inv = 1.0f / ds[a];
    float ta = (los[a] - os[a]) * inv, tb = (his[a] - os[a]) * inv;
    float s = -1;
    if (ta > tb) {
      std::swap(ta, tb);
      s = 1;
    }
    if (ta > t0) {
      t0 = ta;
      axis = a;
      sign = s;
    }
    t1 = std::min(t1, tb);
  }
  if (t0 > t1 || t0 < 1e-4f || t0 >= h.t) return;
  h.t = t0;
  h.normal = {axis == 0 ? sign : 0.f, axis == 1 ? sign : 0.f, axis == 2 ? sign : 0.f};
  h.albedo = albedo;
}

void hit_cylinder(V3 o, V3 d, V3 base, float r, float height, V3 albedo, Hit& h) {
  // Vertical (z-up) capped cylinder: side by the quadratic in x, y; top cap as a plane.
  float ox = o.x - base.x, oy = o.y - base.y;
  float a = d.x * d.x + d.y * d.y, b = ox * d.x + oy * d.y, c = ox * ox + oy * oy - r * r;
  float disc = b * b - a * c;
  if (a > 1e-8f && disc >= 0) {
    float t = (-b - std::sqrt(disc)) / a;
    float z = o.z + t * d.z;
    if (t > 1e-4f && t < h.t && z >= base.z && z <= base.z + height) {
      h.t = t;
      h.normal = normalize({ox + t * d.x, oy + t * d.y, 0});
      h.albedo = albedo;
    }
  }
  if (std::fabs(d.z) > 1e-8f) {
    float t = (base.z + height - o.z) / d.z;
    V3 p = o + d * t;
    if (t > 1e-4f && t < h.t && (p.x - base.x) * (p.x - base.x) + (p.y - base.y) * (p.y - base.y) <= r * r) {
      h.t = t;
      h.normal = {0, 0, 1};
      h.albedo = albedo;
    }
  }
}

Hit trace(V3 o, V3 d) {
  Hit h;
  if (d.z < -1e-6f) {  // checker floor at z = 0, limited to a disc so the horizon shows sky
    float t = -o.z / d.z;
    V3 p = o + d * t;
    if (t > 1e-4f && p.x * p.x + p.y * p.y < 36.0f) {
      bool odd = (static_cast<int>(std::floor(p.x * 1.5f)) + static_cast<int>(std::floor(p.y * 1.5f))) & 1;
      h.t = t;
      h.normal = {0, 0, 1};
      h.albedo = odd ? V3{0.85f, 0.82f, 0.75f} : V3{0.25f, 0.3f, 0.35f};
    }
  }
  hit_sphere(o, d, {0.0f, 0.0f, 0.8f}, 0.8f, {0.85f, 0.2f, 0.15f}, h);
  hit_box(o, d, {1.0f, -1.6f, 0.0f}, {2.0f, -0.6f, 1.0f}, {0.2f, 0.35f, 0.85f}, h);
  hit_cylinder(o, d, {-1.4f, 0.9f, 0.0f}, 0.45f, 1.4f, {0.95f, 0.8f, 0.2f}, h);
  hit_sphere(o, d, {1.2f, 1.4f, 0.35f}, 0.35f, {0.3f, 0.8f, 0.35f}, h);
  return h;
}

float clamp01(float v) { return std::min(1.0f, std::max(0.0f, v)); }

}  // namespace

RgbImage render_content_image(int width, int height, float azimuth_degrees) {
  RgbImage img{width, height, std::vector<float>(3 * static_cast<size_t>(width) * height)};
  const float az = azimuth_degrees * 3.14159265f / 180.0f;
  const V3 eye{5.0f * std::cos(az), 5.0f * std::sin(az), 2.6f}, target{0, 0, 0.6f};
  const V3 fwd = normalize(target - eye), right = normalize(cross(fwd, {0, 0, 1})), up = cross(right, fwd);
  const V3 light = normalize({0.5f, 0.3f, 1.0f});
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
        Hit h = trace(eye, d);
        if (!std::isfinite(h.t)) {
          float k = clamp01(0.5f + 0.5f * d.z);
          col = col + V3{0.55f + 0.3f * k, 0.7f + 0.2f * k, 0.95f};
          continue;
        }
        V3 p = eye + d * h.t;
        float lambert = std::max(0.0f, dot(h.normal, light));
        bool shadow = std::isfinite(trace(p + h.normal * 1e-3f, light).t);
        float shade = 0.25f + 0.75f * (shadow ? 0.0f : lambert);
        col = col + h.albedo * shade;
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
