#include "lib/scene/analytic_scene.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "lib/scene/rays.hpp"

namespace stylerf::scene {

namespace {

constexpr float kEps = 1e-4f;

Float3 operator+(Float3 a, Float3 b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }
Float3 operator-(Float3 a, Float3 b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
Float3 operator*(Float3 a, float s) { return {a[0] * s, a[1] * s, a[2] * s}; }
float dot3(Float3 a, Float3 b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
Float3 unit(Float3 a) { return a * (1.0f / std::sqrt(dot3(a, a))); }

// Each intersector updates (t, normal) when it finds a nearer hit.
bool sphere(const Shape& s, Float3 o, Float3 d, float& t, Float3& n) {
  Float3 oc = o - s.p;
  float b = dot3(oc, d), c = dot3(oc, oc) - s.radius * s.radius, disc = b * b - c;
  if (disc < 0) return false;
  float r = std::sqrt(disc);
  float tt = -b - r;
  if (tt <= kEps) tt = -b + r;  // origin inside the sphere
  if (tt <= kEps || tt >= t) return false;
  t = tt;
  n = unit(o + d * tt - s.p);
  return true;
}

bool box(const Shape& s, Float3 o, Float3 d, float& t, Float3& n) {
  float t0 = -std::numeric_limits<float>::infinity(), t1 = std::numeric_limits<float>::infinity();
  int axis = 0;
  float sign = 1;
  for (int a = 0; a < 3; ++a) {
    if (std::fabs(d[a]) < 1e-12f) {
      if (o[a] < s.p[a] || o[a] > s.q[a]) return false;
      continue;
    }
    float inv = 1.0f / d[a];
    float ta = (s.p[a] - o[a]) * inv, tb = (s.q[a] - o[a]) * inv;
    float sg = -1;  // entering through the min face: outward normal -axis
    if (ta > tb) {
      std::swap(ta, tb);
      sg = 1;
    }
    if (ta > t0) {
      t0 = ta;
      axis = a;
      sign = sg;
    }
    t1 = std::min(t1, tb);
  }
  if (t0 > t1 || t0 <= kEps || t0 >= t) return false;
  t = t0;
  n = {0, 0, 0};
  n[axis] = sign;
  return true;
}

bool cylinder(const Shape& s, Float3 o, Float3 d, float& t, Float3& n) {
  bool found = false;
  const float ox = o[0] - s.p[0], oy = o[1] - s.p[1];
  const float a = d[0] * d[0] + d[1] * d[1], b = ox * d[0] + oy * d[1], c = ox * ox + oy * oy - s.radius * s.radius;
  const float disc = b * b - a * c;
  if (a > 1e-12f && disc >= 0) {
    const float tt = (-b - std::sqrt(disc)) / a;
    const float z = o[2] + tt * d[2];
    if (tt > kEps && tt < t && z >= s.p[2] && z <= s.p[2] + s.height) {
      t = tt;
      n = unit(Float3{ox + tt * d[0], oy + tt * d[1], 0});
      found = true;
    }
  }
  if (std::fabs(d[2]) > 1e-12f) {
    for (int cap = 0; cap < 2; ++cap) {  // bottom (normal -z) and top (normal +z)
      const float zc = s.p[2] + (cap ? s.height : 0.0f);
      const float tt = (zc - o[2]) / d[2];
      const float x = ox + tt * d[0], y = oy + tt * d[1];
      if (tt > kEps && tt < t && x * x + y * y <= s.radius * s.radius) {
        t = tt;
        n = {0, 0, cap ? 1.0f : -1.0f};
        found = true;
      }
    }
  }
  return found;
}

bool disc(const Shape& s, Float3 o, Float3 d, float& t, Float3& n) {
  if (std::fabs(d[2]) < 1e-12f) return false;
  const float tt = (s.p[2] - o[2]) / d[2];
  const float x = o[0] + tt * d[0] - s.p[0], y = o[1] + tt * d[1] - s.p[1];
  if (tt <= kEps || tt >= t || x * x + y * y > s.radius * s.radius) return false;
  t = tt;
  n = {0, 0, o[2] >= s.p[2] ? 1.0f : -1.0f};
  return true;
}

// Value noise: trilinear interpolation of hashed lattice values in [0, 1), smoothstepped.
float lattice(int x, int y, int z) {
  uint32_t h = uint32_t(x) * 73856093u ^ uint32_t(y) * 19349663u ^ uint32_t(z) * 83492791u;
  h ^= h >> 13;
  h *= 0x5bd1e995u;
  h ^= h >> 15;
  return float(h & 0xffffu) / 65536.0f;
}

float value_noise(const Float3& p) {
  const int x = int(std::floor(p[0])), y = int(std::floor(p[1])), z = int(std::floor(p[2]));
  auto fade = [](float t) { return t * t * (3.0f - 2.0f * t); };
  const float fx = fade(p[0] - x), fy = fade(p[1] - y), fz = fade(p[2] - z);
  auto lerp = [](float a, float b, float t) { return a + (b - a) * t; };
  const float x00 = lerp(lattice(x, y, z), lattice(x + 1, y, z), fx);
  const float x10 = lerp(lattice(x, y + 1, z), lattice(x + 1, y + 1, z), fx);
  const float x01 = lerp(lattice(x, y, z + 1), lattice(x + 1, y, z + 1), fx);
  const float x11 = lerp(lattice(x, y + 1, z + 1), lattice(x + 1, y + 1, z + 1), fx);
  return lerp(lerp(x00, x10, fy), lerp(x01, x11, fy), fz);
}

// Four octaves, each twice the frequency and half the weight of the last, with a sharpened contrast.
Float3 noise_albedo(const Material& m, const Float3& l) {
  float v = 0, w = 0.5f, f = 1.0f;
  for (int o = 0; o < 4; ++o, w *= 0.5f, f *= 2.0f) v += w * value_noise(l * f);
  v = std::min(1.0f, std::max(0.0f, (v / 0.9375f - 0.5f) * 2.2f + 0.5f));
  const Float3 ab = m.b + (m.a - m.b) * v;
  return v > 0.8f ? m.c : ab;
}

Float3 albedo_at(const Shape& s, Float3 p) {
  const Material& m = s.material;
  const Float3 l = (p - s.p) * m.frequency;
  auto parity = [](float v) { return int(std::floor(v)) & 1; };
  switch (m.pattern) {
    case Pattern::solid:
      return m.a;
    case Pattern::checker:
      // A disc is flat, so its checker is 2D; solids use a 3D (solid) checker, which textures any surface.
      if (s.kind == Shape::Kind::disc) return (parity(l[0]) ^ parity(l[1])) ? m.a : m.b;
      return (parity(l[0]) ^ parity(l[1]) ^ parity(l[2])) ? m.a : m.b;
    case Pattern::stripes:
      return parity(l[2]) ? m.a : m.b;
    case Pattern::noise:
      return noise_albedo(m, l);
  }
  return m.a;
}

}  // namespace

SurfaceHit AnalyticScene::trace(const Float3& o, const Float3& d) const {
  SurfaceHit h;
  float t = std::numeric_limits<float>::infinity();
  Float3 n{};
  const Shape* hit = nullptr;
  for (const Shape& s : shapes) {
    bool found = false;
    switch (s.kind) {
      case Shape::Kind::sphere: found = sphere(s, o, d, t, n); break;
      case Shape::Kind::box: found = box(s, o, d, t, n); break;
      case Shape::Kind::cylinder: found = cylinder(s, o, d, t, n); break;
      case Shape::Kind::disc: found = disc(s, o, d, t, n); break;
    }
    if (found) hit = &s;
  }
  if (!hit) return h;
  h.hit = true;
  h.t = t;
  h.point = o + d * t;
  h.normal = n;
  h.albedo = albedo_at(*hit, h.point);
  return h;
}

Float3 AnalyticScene::shade(const SurfaceHit& h) const {
  float direct = std::max(0.0f, dot3(h.normal, light));
  if (shadows && direct > 0 && trace(h.point + h.normal * 1e-3f, light).hit) direct = 0;
  const float k = ambient + (1.0f - ambient) * direct;
  return {std::min(1.0f, h.albedo[0] * k), std::min(1.0f, h.albedo[1] * k), std::min(1.0f, h.albedo[2] * k)};
}

AnalyticScene AnalyticScene::objects() {
  AnalyticScene s;
  Shape ball;
  ball.kind = Shape::Kind::sphere;
  ball.p = {0.35f, -0.35f, 0.05f};
  ball.radius = 0.6f;
  ball.material = {{0.9f, 0.25f, 0.15f}, {0.95f, 0.85f, 0.7f}, Pattern::checker, 3.0f};
  Shape cube;
  cube.kind = Shape::Kind::box;
  cube.p = {-1.05f, 0.05f, -0.8f};
  cube.q = {-0.2f, 0.9f, 0.05f};
  cube.material = {{0.15f, 0.3f, 0.85f}, {0.9f, 0.9f, 0.95f}, Pattern::checker, 2.5f};
  Shape can;
  can.kind = Shape::Kind::cylinder;
  can.p = {0.45f, 0.7f, -0.9f};
  can.radius = 0.35f;
  can.height = 1.4f;
  can.material = {{0.95f, 0.8f, 0.15f}, {0.2f, 0.6f, 0.3f}, Pattern::stripes, 5.0f};
  Shape bead;
  bead.kind = Shape::Kind::sphere;
  bead.p = {-0.6f, -0.75f, 0.55f};
  bead.radius = 0.3f;
  bead.material = {{0.3f, 0.8f, 0.4f}, {0.3f, 0.8f, 0.4f}, Pattern::solid, 1.0f};
  s.shapes = {ball, cube, can, bead};
  return s;
}

AnalyticScene AnalyticScene::on_floor() {
  AnalyticScene s;
  s.ambient = 0.25f;
  Shape floor;
  floor.kind = Shape::Kind::disc;
  floor.radius = 6.0f;
  floor.material = {{0.85f, 0.82f, 0.75f}, {0.25f, 0.3f, 0.35f}, Pattern::checker, 1.5f};
  Shape ball;
  ball.p = {0.0f, 0.0f, 0.8f};
  ball.radius = 0.8f;
  ball.material.a = {0.85f, 0.2f, 0.15f};
  Shape cube;
  cube.kind = Shape::Kind::box;
  cube.p = {1.0f, -1.6f, 0.0f};
  cube.q = {2.0f, -0.6f, 1.0f};
  cube.material.a = {0.2f, 0.35f, 0.85f};
  Shape can;
  can.kind = Shape::Kind::cylinder;
  can.p = {-1.4f, 0.9f, 0.0f};
  can.radius = 0.45f;
  can.height = 1.4f;
  can.material.a = {0.95f, 0.8f, 0.2f};
  Shape bead;
  bead.p = {1.2f, 1.4f, 0.35f};
  bead.radius = 0.35f;
  bead.material.a = {0.3f, 0.8f, 0.35f};
  s.shapes = {floor, ball, cube, can, bead};
  return s;
}

AnalyticView render_analytic(const AnalyticScene& scene, const Camera& cam, int ss) {
  AnalyticView v;
  const size_t n = size_t(cam.width) * cam.height;
  v.rgb.assign(3 * n, 0.0f);
  v.alpha.assign(n, 0.0f);
  v.depth.assign(n, 0.0f);
  ss = std::max(1, ss);
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      const size_t i = size_t(y) * cam.width + x;
      float o[3], d[3];
      pixel_ray(cam, x + 0.5f, y + 0.5f, o, d);
      const SurfaceHit centre = scene.trace({o[0], o[1], o[2]}, {d[0], d[1], d[2]});
      if (centre.hit) v.depth[i] = centre.t;
      Float3 sum{0, 0, 0};
      int hits = 0;
      for (int sy = 0; sy < ss; ++sy)
        for (int sx = 0; sx < ss; ++sx) {
          pixel_ray(cam, x + (sx + 0.5f) / ss, y + (sy + 0.5f) / ss, o, d);
          const SurfaceHit h = scene.trace({o[0], o[1], o[2]}, {d[0], d[1], d[2]});
          if (!h.hit) continue;
          sum = sum + scene.shade(h);
          ++hits;
        }
      if (hits) {
        for (int c = 0; c < 3; ++c) v.rgb[3 * i + c] = sum[c] / hits;
        v.alpha[i] = float(hits) / (ss * ss);
      }
    }
  return v;
}

AnalyticScene AnalyticScene::textured() {
  AnalyticScene s = objects();
  const Float3 colours[4][3] = {{{0.9f, 0.3f, 0.1f}, {0.15f, 0.1f, 0.3f}, {1.0f, 0.9f, 0.4f}},
                                {{0.2f, 0.4f, 0.9f}, {0.05f, 0.15f, 0.1f}, {0.9f, 0.95f, 1.0f}},
                                {{0.9f, 0.8f, 0.2f}, {0.3f, 0.1f, 0.05f}, {0.4f, 1.0f, 0.5f}},
                                {{0.3f, 0.9f, 0.5f}, {0.1f, 0.05f, 0.2f}, {1.0f, 0.5f, 0.8f}}};
  for (size_t i = 0; i < s.shapes.size(); ++i)
    s.shapes[i].material = {colours[i][0], colours[i][1], Pattern::noise, 6.0f, colours[i][2]};
  Shape floor;
  floor.kind = Shape::Kind::disc;
  floor.p = {0.0f, 0.0f, -0.9f};
  floor.radius = 2.4f;
  floor.material = {{0.75f, 0.7f, 0.6f}, {0.15f, 0.2f, 0.25f}, Pattern::noise, 3.0f, {0.9f, 0.3f, 0.3f}};
  s.shapes.push_back(floor);
  return s;
}

}  // namespace stylerf::scene
