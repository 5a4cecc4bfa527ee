#include "lib/scene/camera_path.hpp"

#include <algorithm>
#include <cmath>

#include "host/error.hpp"
#include "lib/scene/poses.hpp"

namespace stylerf::scene {

namespace {

void need_views(const Scene& s, int frames) {
  if (s.train.empty()) throw host::Error("camera path: scene " + s.name + " has no training views");
  if (frames < 1) throw host::Error("camera path: need at least one frame");
}

}  // namespace

double path_focus_depth(const Scene& scene) {
  // dt = 0.75 of the way in inverse depth, as LLFF renders.
  const double close = scene.depth_near * 0.9, inf = scene.depth_far * 5.0, dt = 0.75;
  return close > 0 && inf > 0 ? 1.0 / ((1.0 - dt) / close + dt / inf) : 1.0;
}

std::vector<Camera> spiral_path(const Scene& scene, int frames) {
  need_views(scene, frames);
  std::vector<Pose> poses;
  for (const View& v : scene.train) poses.push_back(pose_of(v.camera));
  for (const View& v : scene.test) poses.push_back(pose_of(v.camera));
  const Pose avg = average_pose(poses);
  const Vec3 up = normalize(avg.axis(1));
  const double focal = path_focus_depth(scene);
  // Radii: 90th percentile of |position| per axis in the (recentred) world frame.
  Vec3 rads;
  for (int k = 0; k < 3; ++k) {
    std::vector<double> v;
    for (const Pose& p : poses) v.push_back(std::fabs(p.m[k][3] - avg.m[k][3]));
    std::sort(v.begin(), v.end());
    rads[k] = v[std::min(v.size() - 1, size_t(0.9 * (v.size() - 1) + 0.5))];
  }
  const double turns = 2.0, zrate = 0.5;
  std::vector<Camera> out;
  for (int f = 0; f < frames; ++f) {
    const double th = 2.0 * M_PI * turns * f / frames;
    const Vec3 local{std::cos(th) * rads[0], -std::sin(th) * rads[1], -std::sin(th * zrate) * rads[2]};
    Vec3 centre = avg.axis(3);
    for (int k = 0; k < 3; ++k) centre = add(centre, scale(avg.axis(k), local[k]));
    const Vec3 target = sub(avg.axis(3), scale(avg.axis(2), focal));  // on the average view axis
    out.push_back(with_pose(scene.train[0].camera, view_matrix(sub(centre, target), up, centre)));
  }
  return out;
}

std::vector<Camera> orbit_path(const Scene& scene, int frames) {
  need_views(scene, frames);
  double radius = 0, elevation = 0;
  for (const View& v : scene.train) {
    const auto p = v.camera.position();
    const double r = std::sqrt(double(p[0]) * p[0] + double(p[1]) * p[1] + double(p[2]) * p[2]);
    radius += r / scene.train.size();
    elevation += std::asin(std::clamp(p[2] / r, -1.0, 1.0)) / scene.train.size();
  }
  std::vector<Camera> out;
  for (int f = 0; f < frames; ++f) {
    const double az = 2.0 * M_PI * f / frames;
    const Vec3 eye{radius * std::cos(elevation) * std::cos(az), radius * std::cos(elevation) * std::sin(az),
                   radius * std::sin(elevation)};
    out.push_back(with_pose(scene.train[0].camera, look_at(eye, {0, 0, 0}, {0, 0, 1})));
  }
  return out;
}

std::vector<Camera> default_path(const Scene& scene, int frames) {
  const std::string& f = scene.format;
  const bool forward = f.size() >= 8 && f.compare(f.size() - 8, 8, "-forward") == 0;
  return forward || scene.effects.ndc ? spiral_path(scene, frames) : orbit_path(scene, frames);
}

}  // namespace stylerf::scene
