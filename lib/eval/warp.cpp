#include "lib/eval/warp.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "host/error.hpp"
#include "lib/eval/finite_image.hpp"

namespace stylerf::eval {

using host::Error;
using Vec3 = std::array<double, 3>;

RaySpace RaySpace::of(const scene::Scene& scene) { return {scene.effects.ndc, scene.ndc_near}; }

namespace {

// World-space unit ray through a continuous pixel position (rays.hpp's pixel_ray, in double).
void pixel_ray(const scene::Camera& cam, double px, double py, Vec3& o, Vec3& d) {
  const double dc[3] = {(px - cam.cx) / cam.fx, -(py - cam.cy) / cam.fy, -1.0};
  double n2 = 0;
  for (int r = 0; r < 3; ++r) {
    d[r] = cam.c2w[r][0] * dc[0] + cam.c2w[r][1] * dc[1] + cam.c2w[r][2] * dc[2];
    o[r] = cam.c2w[r][3];
    n2 += d[r] * d[r];
  }
  for (double& v : d) v /= std::sqrt(n2);
}

// Camera-space coordinates of a world point (x right, y up, looking down -z).
Vec3 to_camera(const scene::Camera& cam, const Vec3& p) {
  const double d[3] = {p[0] - cam.c2w[0][3], p[1] - cam.c2w[1][3], p[2] - cam.c2w[2][3]};
  Vec3 c{};
  for (int a = 0; a < 3; ++a) c[a] = cam.c2w[0][a] * d[0] + cam.c2w[1][a] * d[1] + cam.c2w[2][a] * d[2];
  return c;
}

double distance(const Vec3& a, const Vec3& b) {
  return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

void check_frame(const FrameGeometry& f, const char* which) {
  const size_t n = size_t(f.camera.width) * size_t(f.camera.height);
  if (f.camera.width < 1 || f.camera.height < 1)
    throw Error(std::string("warp: frame ") + which + " has an empty camera");
  if (f.depth.size() != n || f.opacity.size() != n)
    throw Error(std::string("warp: frame ") + which + " needs depth and opacity of " + std::to_string(n) +
                " pixels (" + std::to_string(f.camera.width) + "x" + std::to_string(f.camera.height) + "), got " +
                std::to_string(f.depth.size()) + " and " + std::to_string(f.opacity.size()));
  // A renderer reports empty rays as depth 0 and opacity 0; NaN is a numerical failure upstream, and
  // leaving such pixels out would score a broken render on whatever is left.
  for (size_t i = 0; i < n; ++i)
    if (std::isnan(f.depth[i]) || std::isnan(f.opacity[i]))
      throw Error(std::string("warp: frame ") + which + " has a NaN " + (std::isnan(f.depth[i]) ? "depth" : "opacity") +
                  " at pixel " + std::to_string(i % size_t(f.camera.width)) + "," +
                  std::to_string(i / size_t(f.camera.width)) + " (a failed render, not empty space)");
}

}  // namespace

Vec3 world_point(const scene::Camera& cam, double px, double py, double t, const RaySpace& space, double ndc_far,
                 bool* finite) {
  Vec3 o, d;
  pixel_ray(cam, px, py, o, d);
  if (finite) *finite = std::isfinite(t);
  if (!space.ndc) return {o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]};
  // rays.hpp's to_ndc in double: the origin moved to the plane z = -near, then projected.
  const double near = space.ndc_near;
  const double s = -(near + o[2]) / d[2];
  const double ox = o[0] + s * d[0], oy = o[1] + s * d[1], oz = o[2] + s * d[2];
  const double ax = -2.0 * cam.fx / cam.width, ay = -2.0 * cam.fy / cam.height;
  const Vec3 on{ax * ox / oz, ay * oy / oz, 1.0 + 2.0 * near / oz};
  const Vec3 dn{ax * (d[0] / d[2] - ox / oz), ay * (d[1] / d[2] - oy / oz), -2.0 * near / oz};
  const Vec3 p{on[0] + t * dn[0], on[1] + t * dn[1], on[2] + t * dn[2]};
  // NDC z = 1 + 2 near / z  ->  z = 2 near / (NDC z - 1); t -> 1 is z -> -infinity.
  if (finite && t >= ndc_far) *finite = false;
  const double z = 2.0 * near / (p[2] - 1.0);
  return {p[0] * z / ax, p[1] * z / ay, z};
}

Correspondence correspond(const FrameGeometry& t, const FrameGeometry& s, const RaySpace& space,
                          const WarpOptions& opt) {
  check_frame(t, "t");
  check_frame(s, "s");
  if (!(opt.depth_tolerance > 0)) throw Error("warp: the depth tolerance must be > 0");
  const int W = t.camera.width, H = t.camera.height, Ws = s.camera.width, Hs = s.camera.height;
  Correspondence c;
  c.width = W;
  c.height = H;
  c.x.assign(size_t(W) * H, 0.0f);
  c.y.assign(size_t(W) * H, 0.0f);
  c.valid.assign(size_t(W) * H, 0);
  const Vec3 cs{s.camera.c2w[0][3], s.camera.c2w[1][3], s.camera.c2w[2][3]};
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const size_t i = size_t(y) * W + x;
      if (opt.mask_background && !(t.opacity[i] >= opt.min_opacity)) {
        ++c.stats.background;
        continue;
      }
      const double dt = t.depth[i];
      // Depth 0 is what a renderer reports for an empty ray (in world space it would be the camera centre);
      // a ray with no opacity has no surface whatever its depth says.
      if (!std::isfinite(dt) || (!space.ndc && !(dt > 0)) || (space.ndc && dt < 0) || !(t.opacity[i] > 1e-6f)) {
        ++c.stats.no_depth;
        continue;
      }
      bool finite = true;
      const Vec3 X = world_point(t.camera, x + 0.5, y + 0.5, dt, space, opt.ndc_far, &finite);
      if (!finite) {
        ++c.stats.no_depth;
        continue;
      }
      const Vec3 pc = to_camera(s.camera, X);
      if (!(pc[2] < 0)) {
        ++c.stats.off_image;
        continue;
      }
      const double qx = s.camera.cx + s.camera.fx * pc[0] / -pc[2];
      const double qy = s.camera.cy - s.camera.fy * pc[1] / -pc[2];
      if (!(qx >= 0.5 && qx <= Ws - 0.5 && qy >= 0.5 && qy <= Hs - 0.5)) {
        ++c.stats.off_image;
        continue;
      }
      // The bilinear sample reads the 2x2 pixels around q: each must show frame s's surface at X (not
      // empty space, not an occluder), or the sample would mix in colours from elsewhere (silhouettes).
      const int x0 = std::min(Ws - 2, std::max(0, int(std::floor(qx - 0.5))));
      const int y0 = std::min(Hs - 2, std::max(0, int(std::floor(qy - 0.5))));
      const double r_x = distance(X, cs);
      bool background = false, occluded = false;
      for (int n = 0; n < 4 && !background; ++n) {
        const int nx = std::min(Ws - 1, x0 + (n & 1)), ny = std::min(Hs - 1, y0 + (n >> 1));
        const size_t j = size_t(ny) * Ws + nx;
        if (opt.mask_background && !(s.opacity[j] >= opt.min_opacity)) {
          background = true;
          break;
        }
        // Occlusion: frame s's own surface along that pixel, compared as world distances from camera s.
        const double ds = s.depth[j];
        bool s_finite = std::isfinite(ds) && (space.ndc ? ds >= 0 : ds > 0) && s.opacity[j] > 1e-6f;
        const Vec3 Xs = s_finite ? world_point(s.camera, nx + 0.5, ny + 0.5, ds, space, opt.ndc_far, &s_finite) : Vec3{};
        if (!s_finite || std::abs(r_x - distance(Xs, cs)) > opt.depth_tolerance * r_x) occluded = true;
      }
      if (background) {
        ++c.stats.background;
        continue;
      }
      if (occluded) {
        ++c.stats.occluded;
        continue;
      }
      c.x[i] = float(qx);
      c.y[i] = float(qy);
      c.valid[i] = 1;
      ++c.stats.valid;
    }
  return c;
}

void add_shell_surface(FrameGeometry& f, float radius, float min_opacity) {
  check_frame(f, "shell");
  if (!(radius > 0)) throw Error("add_shell_surface: the shell's radius must be > 0 (got " + std::to_string(radius) + ")");
  const int W = f.camera.width, H = f.camera.height;
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const size_t i = size_t(y) * W + x;
      if (f.opacity[i] >= min_opacity) continue;
      Vec3 o, d;
      pixel_ray(f.camera, x + 0.5, y + 0.5, o, d);  // world_point's unit ray
      // |o + t d| = radius with |d| = 1: t^2 + 2 (o.d) t + (o.o - r^2) = 0; the larger root is the exit.
      const double b = o[0] * d[0] + o[1] * d[1] + o[2] * d[2];
      const double c = o[0] * o[0] + o[1] * o[1] + o[2] * o[2] - double(radius) * radius;
      if (!(c < 0)) continue;  // the camera is outside the sphere: the shell is at infinity there
      f.depth[i] = float(-b + std::sqrt(b * b - c));
      f.opacity[i] = 1.0f;
    }
}

BilinearTaps bilinear_taps(double qx, double qy, int width, int height) {
  // Between pixel centres: position q - 0.5 in index units.
  const double fx = std::clamp(qx - 0.5, 0.0, double(width - 1));
  const double fy = std::clamp(qy - 0.5, 0.0, double(height - 1));
  const int x0 = std::min(int(fx), width - 1), y0 = std::min(int(fy), height - 1);
  const int x1 = std::min(x0 + 1, width - 1), y1 = std::min(y0 + 1, height - 1);
  const double ax = fx - x0, ay = fy - y0;
  return {{x0, x1, x0, x1}, {y0, y0, y1, y1}, {(1 - ax) * (1 - ay), ax * (1 - ay), (1 - ax) * ay, ax * ay}};
}

io::Image warp_image(const io::Image& s, const Correspondence& c, const io::Image& fill) {
  if (fill.width != c.width || fill.height != c.height)
    throw Error("warp_image: the fill image is " + std::to_string(fill.width) + "x" + std::to_string(fill.height) +
                ", the correspondence " + std::to_string(c.width) + "x" + std::to_string(c.height));
  if (s.width < 1 || s.height < 1 || s.data.size() != size_t(3) * s.width * s.height)
    throw Error("warp_image: the source image is empty or its data does not match its size");
  io::Image out = fill;
  for (int y = 0; y < c.height; ++y)
    for (int x = 0; x < c.width; ++x) {
      const size_t i = size_t(y) * c.width + x;
      if (!c.valid[i]) continue;
      const BilinearTaps t = bilinear_taps(c.x[i], c.y[i], s.width, s.height);
      for (int ch = 0; ch < 3; ++ch) {
        double v = 0;
        for (int k = 0; k < 4; ++k) v += t.w[k] * s.at(ch, t.y[k], t.x[k]);
        out.at(ch, y, x) = float(v);
      }
    }
  return out;
}

double masked_rmse(const io::Image& a, const io::Image& b, const std::vector<uint8_t>& valid) {
  if (a.width != b.width || a.height != b.height || valid.size() != size_t(a.width) * a.height)
    throw Error("masked_rmse: images of " + std::to_string(a.width) + "x" + std::to_string(a.height) + " and " +
                std::to_string(b.width) + "x" + std::to_string(b.height) + " with a mask of " +
                std::to_string(valid.size()) + " pixels");
  for (const io::Image* im : {&a, &b})
    if (const std::string bad = non_finite_at(*im); !bad.empty())
      throw Error(std::string("masked_rmse: image ") + (im == &a ? "a" : "b") + " has " + bad);
  double sum = 0;
  int64_t n = 0;
  const size_t plane = size_t(a.width) * a.height;
  for (size_t i = 0; i < plane; ++i) {
    if (!valid[i]) continue;
    for (int ch = 0; ch < 3; ++ch) {
      const double d = double(a.data[ch * plane + i]) - b.data[ch * plane + i];
      sum += d * d;
    }
    n += 3;
  }
  return n ? std::sqrt(sum / double(n)) : std::numeric_limits<double>::quiet_NaN();
}

std::vector<float> mask_weights(const std::vector<uint8_t>& valid) {
  std::vector<float> w(valid.size());
  for (size_t i = 0; i < valid.size(); ++i) w[i] = valid[i] ? 1.0f : 0.0f;
  return w;
}

}  // namespace stylerf::eval
