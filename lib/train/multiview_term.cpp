#include "lib/train/multiview_term.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "host/error.hpp"

namespace stylerf::train {

using host::Error;

scene::Camera patch_camera(const scene::Camera& view, int x0, int y0, int width, int height) {
  scene::Camera c = view;
  c.cx -= float(x0);
  c.cy -= float(y0);
  c.width = width;
  c.height = height;
  return c;
}

eval::FrameGeometry patch_geometry(const scene::Camera& camera, int map_w, int map_h, int stride,
                                   const std::vector<float>& depth_sum, const std::vector<float>& acc) {
  const size_t n = size_t(map_w) * size_t(map_h);
  if (map_w < 1 || map_h < 1 || stride < 1 || depth_sum.size() != n || acc.size() != n)
    throw Error("patch_geometry: a map of " + std::to_string(map_w) + "x" + std::to_string(map_h) + " blocks needs " +
                std::to_string(n) + " depths and opacities, got " + std::to_string(depth_sum.size()) + " and " +
                std::to_string(acc.size()));
  const int W = camera.width, H = camera.height;
  eval::FrameGeometry g;
  g.camera = camera;
  g.depth.assign(size_t(W) * H, 0.0f);
  g.opacity.assign(size_t(W) * H, 0.0f);
  // Block j's ray passes through pixel position stride j + stride / 2: map coordinate (x + 0.5) / stride - 0.5.
  auto coord = [stride](int x, int size, int& i0, int& i1, double& a) {
    const double u = std::clamp((x + 0.5) / stride - 0.5, 0.0, double(size - 1));
    i0 = std::min(int(u), size - 1);
    i1 = std::min(i0 + 1, size - 1);
    a = u - i0;
  };
  for (int y = 0; y < H; ++y) {
    int y0, y1;
    double ay;
    coord(y, map_h, y0, y1, ay);
    for (int x = 0; x < W; ++x) {
      int x0, x1;
      double ax;
      coord(x, map_w, x0, x1, ax);
      auto lerp = [&](const std::vector<float>& m) {
        const double top = (1 - ax) * m[size_t(y0) * map_w + x0] + ax * m[size_t(y0) * map_w + x1];
        const double bottom = (1 - ax) * m[size_t(y1) * map_w + x0] + ax * m[size_t(y1) * map_w + x1];
        return (1 - ay) * top + ay * bottom;
      };
      const double a = lerp(acc), d = lerp(depth_sum);
      const size_t i = size_t(y) * W + x;
      g.opacity[i] = float(a);
      g.depth[i] = a > 1e-6 ? float(d / a) : 0.0f;
    }
  }
  return g;
}

namespace {
using Vec3 = std::array<double, 3>;

Vec3 unit_from(const Vec3& from, const float* to_xyz) {
  Vec3 d{to_xyz[0] - from[0], to_xyz[1] - from[1], to_xyz[2] - from[2]};
  const double n = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  for (double& v : d) v /= std::max(n, 1e-12);
  return d;
}

int corner(float centre, int patch, int size) {
  const int hi = std::max(0, (size - patch) / 4 * 4);
  return std::clamp(int(std::lround((centre - patch / 2.0) / 4.0)) * 4, 0, hi);
}
}  // namespace

SecondPatch pick_second_patch(const scene::Scene& scene, const eval::FrameGeometry& first, int first_view,
                              int patch_w, int patch_h, float max_angle_deg, const eval::RaySpace& space,
                              std::mt19937_64& draw) {
  Vec3 X{0, 0, 0};
  int64_t points = 0;
  const int W = first.camera.width, H = first.camera.height;
  for (int y = 0; y < H; y += 4)
    for (int x = 0; x < W; x += 4) {
      const size_t i = size_t(y) * W + x;
      if (!(first.opacity[i] >= 0.5f) || !(space.ndc ? first.depth[i] >= 0 : first.depth[i] > 0)) continue;
      bool finite = true;
      const Vec3 p = eval::world_point(first.camera, x + 0.5, y + 0.5, first.depth[i], space, 0.999, &finite);
      if (!finite) continue;
      for (int a = 0; a < 3; ++a) X[a] += p[a];
      ++points;
    }
  SecondPatch out;
  if (points == 0) return out;
  for (double& v : X) v /= double(points);
  const float c1[3] = {first.camera.c2w[0][3], first.camera.c2w[1][3], first.camera.c2w[2][3]};
  const Vec3 u1 = unit_from(X, c1);
  const double min_cos = std::cos(double(max_angle_deg) * M_PI / 180.0);
  std::vector<int> candidates;
  std::vector<std::array<float, 2>> at;
  for (size_t v = 0; v < scene.train.size(); ++v) {
    if (int(v) == first_view) continue;
    const scene::Camera& cam = scene.train[v].camera;
    const float cv[3] = {cam.c2w[0][3], cam.c2w[1][3], cam.c2w[2][3]};
    const Vec3 uv = unit_from(X, cv);
    if (u1[0] * uv[0] + u1[1] * uv[1] + u1[2] * uv[2] < min_cos) continue;
    float px, py;
    if (!cam.project({float(X[0]), float(X[1]), float(X[2])}, px, py)) continue;
    if (!(px >= 0 && px <= cam.width && py >= 0 && py <= cam.height)) continue;
    candidates.push_back(int(v));
    at.push_back({px, py});
  }
  if (candidates.empty()) return out;
  const size_t k = std::uniform_int_distribution<size_t>(0, candidates.size() - 1)(draw);
  const scene::Camera& cam = scene.train[size_t(candidates[k])].camera;
  out.view = candidates[k];
  out.x0 = corner(at[k][0], patch_w, cam.width);
  out.y0 = corner(at[k][1], patch_h, cam.height);
  return out;
}

MultiviewLoss multiview_loss(const io::Image& a, const io::Image& b, const eval::Correspondence& c, float weight) {
  const size_t n = size_t(c.width) * size_t(c.height);
  if (a.width != c.width || a.height != c.height || a.data.size() != 3 * n || c.valid.size() != n ||
      b.width < 1 || b.height < 1 || b.data.size() != size_t(3) * b.width * b.height)
    throw Error("multiview_loss: pictures of " + std::to_string(a.width) + "x" + std::to_string(a.height) + " and " +
                std::to_string(b.width) + "x" + std::to_string(b.height) + " with a correspondence of " +
                std::to_string(c.width) + "x" + std::to_string(c.height));
  for (const io::Image* img : {&a, &b})
    for (size_t i = 0; i < img->data.size(); ++i)
      if (!std::isfinite(img->data[i]))
        throw Error(std::string("multiview_loss: the ") + (img == &a ? "first" : "second") +
                    " picture holds a NaN or infinite value at channel " + std::to_string(i / (img->data.size() / 3)) +
                    ", pixel " + std::to_string(i % (img->data.size() / 3)));
  MultiviewLoss out;
  out.d_first = {a.width, a.height, std::vector<float>(a.data.size(), 0.0f)};
  out.d_second = {b.width, b.height, std::vector<float>(b.data.size(), 0.0f)};
  for (size_t i = 0; i < n; ++i) out.pixels += c.valid[i] ? 1 : 0;
  if (out.pixels == 0) return out;
  const double scale = double(weight) / (3.0 * double(out.pixels));
  double sum = 0;
  for (int y = 0; y < c.height; ++y)
    for (int x = 0; x < c.width; ++x) {
      const size_t i = size_t(y) * c.width + x;
      if (!c.valid[i]) continue;
      // eval::warp_image's sample, and its transpose for the gradient.
      const eval::BilinearTaps t = eval::bilinear_taps(c.x[i], c.y[i], b.width, b.height);
      for (int ch = 0; ch < 3; ++ch) {
        double s = 0;
        for (int k = 0; k < 4; ++k) s += t.w[k] * b.at(ch, t.y[k], t.x[k]);
        const double r = double(a.at(ch, y, x)) - s;
        sum += r * r;
        const double g = 2.0 * scale * r;
        out.d_first.at(ch, y, x) = float(g);
        for (int k = 0; k < 4; ++k) out.d_second.at(ch, t.y[k], t.x[k]) -= float(g * t.w[k]);
      }
    }
  out.value = scale * sum;
  return out;
}

}  // namespace stylerf::train
