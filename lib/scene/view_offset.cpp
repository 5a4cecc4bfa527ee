#include "lib/scene/view_offset.hpp"

#include <algorithm>
#include <cmath>

#include "host/error.hpp"
#include "lib/scene/camera_path.hpp"
#include "lib/scene/poses.hpp"

namespace stylerf::scene {

namespace {

// Rodrigues: v rotated about the unit axis a by angle t.
Vec3 rotate(Vec3 v, Vec3 a, double t) {
  const double c = std::cos(t), s = std::sin(t);
  return add(add(scale(v, c), scale(cross(a, v), s)), scale(a, dot(a, v) * (1 - c)));
}

// Every column of p (axes and position) rotated about the unit axis a through the origin.
Pose rotate_pose(const Pose& p, Vec3 a, double t) {
  Pose out;
  for (int k = 0; k < 4; ++k) {
    const Vec3 v = rotate(p.axis(k), a, t);
    for (int r = 0; r < 3; ++r) out.m[r][k] = v[r];
  }
  return out;
}

Camera orbit_camera(const Camera& base, const ViewOffset& o) {
  Pose p = pose_of(base);
  const Vec3 pos = p.axis(3);
  const double r = norm(pos);
  if (r < 1e-9) return base;  // a camera at the centre has nothing to orbit around
  const double el = std::asin(std::clamp(pos[2] / r, -1.0, 1.0));
  const double d_el = std::clamp(el + o.pitch, -kMaxElevation, kMaxElevation) - el;
  // Elevation first, about the horizontal axis perpendicular to the camera's azimuth (pos x up); at a pole
  // that axis is undefined and the camera's own right axis stands in.
  Vec3 axis = cross(pos, {0, 0, 1});
  axis = norm(axis) > 1e-9 ? normalize(axis) : normalize(p.axis(0));
  if (d_el != 0) p = rotate_pose(p, axis, d_el);
  if (o.yaw != 0) p = rotate_pose(p, {0, 0, 1}, o.yaw);
  const double s = std::exp(-o.zoom);
  for (int k = 0; k < 3; ++k) p.m[k][3] *= s;
  return with_pose(base, p);
}

// The capture's span for forward-facing scenes: mean pose and 90th-percentile offsets along its axes.
struct ForwardSpan {
  Pose avg;
  Vec3 rads{};
};

ForwardSpan forward_span(const Scene& scene) {
  std::vector<Pose> poses;
  for (const View& v : scene.train) poses.push_back(pose_of(v.camera));
  for (const View& v : scene.test) poses.push_back(pose_of(v.camera));
  ForwardSpan s;
  s.avg = average_pose(poses);
  for (int k = 0; k < 3; ++k) {
    std::vector<double> v;
    for (const Pose& p : poses) v.push_back(std::fabs(dot(sub(p.axis(3), s.avg.axis(3)), s.avg.axis(k))));
    std::sort(v.begin(), v.end());
    s.rads[k] = v[std::min(v.size() - 1, size_t(0.9 * double(v.size() - 1) + 0.5))];
  }
  // Captures swept sideways barely move forward: let zoom travel as far as the sideways span at least half.
  s.rads[2] = std::max(s.rads[2], 0.25 * (s.rads[0] + s.rads[1]));
  return s;
}

Camera forward_camera(const Scene& scene, const Camera& base, const ViewOffset& o) {
  const ForwardSpan span = forward_span(scene);
  const Pose p = pose_of(base);
  // The point the view looked at: on its axis at the spiral path's focus depth (mostly the near content).
  const double focal = path_focus_depth(scene);
  const Vec3 target = sub(p.axis(3), scale(p.axis(2), focal));
  Vec3 eye = p.axis(3);
  eye = add(eye, scale(span.avg.axis(0), o.yaw * span.rads[0]));
  eye = add(eye, scale(span.avg.axis(1), o.pitch * span.rads[1]));
  eye = sub(eye, scale(span.avg.axis(2), o.zoom * span.rads[2]));
  return with_pose(base, view_matrix(sub(eye, target), p.axis(1), eye));
}

void check_finite(const ViewOffset& o) {
  if (!std::isfinite(o.yaw) || !std::isfinite(o.pitch) || !std::isfinite(o.zoom))
    throw host::Error("camera offset: yaw, pitch and zoom must be finite numbers");
}

}  // namespace

ViewKind view_kind(const Scene& scene) {
  const std::string& f = scene.format;
  const bool forward = f.size() >= 8 && f.compare(f.size() - 8, 8, "-forward") == 0;
  return forward || scene.effects.ndc ? ViewKind::Forward : ViewKind::Orbit;
}

const char* view_kind_name(ViewKind k) { return k == ViewKind::Forward ? "forward" : "orbit"; }

ViewLimits view_limits(ViewKind kind) {
  ViewLimits l;
  if (kind == ViewKind::Forward) {
    l.yaw = {-1, 1};
    l.pitch = {-1, 1};
  } else {
    l.yaw = {-1e6, 1e6};  // any number of turns
    l.pitch = {-2 * kMaxElevation, 2 * kMaxElevation};  // the elevation itself is kept within +-kMaxElevation
  }
  l.zoom = {-1, 1};
  return l;
}

ViewOffset clamp_offset(const ViewOffset& o, ViewKind kind) {
  check_finite(o);
  const ViewLimits l = view_limits(kind);
  ViewOffset c = o;
  c.yaw = std::clamp(o.yaw, l.yaw[0], l.yaw[1]);
  c.pitch = std::clamp(o.pitch, l.pitch[0], l.pitch[1]);
  c.zoom = std::clamp(o.zoom, l.zoom[0], l.zoom[1]);
  return c;
}

Camera offset_camera(const Scene& scene, const ViewOffset& o, int longer) {
  if (o.view < 0 || size_t(o.view) >= scene.train.size())
    throw host::Error("camera offset: view " + std::to_string(o.view) + " is not a training view of " + scene.name +
                      " (0.." + std::to_string(int(scene.train.size()) - 1) + ")");
  const ViewKind kind = view_kind(scene);
  const ViewOffset c = clamp_offset(o, kind);
  const Camera& base = scene.train[size_t(c.view)].camera;
  Camera cam = base;
  if (c.yaw != 0 || c.pitch != 0 || c.zoom != 0)
    cam = kind == ViewKind::Forward ? forward_camera(scene, base, c) : orbit_camera(base, c);
  return cam.with_longer_side(longer);
}

std::vector<ViewOffset> orbit_offsets(const ViewOffset& start, ViewKind kind, int frames) {
  if (frames < 1) throw host::Error("orbit: need at least one frame");
  check_finite(start);
  std::vector<ViewOffset> out;
  constexpr double kTwoPi = 6.283185307179586;
  for (int f = 0; f < frames; ++f) {
    const double t = kTwoPi * f / frames;
    ViewOffset o = start;
    if (kind == ViewKind::Orbit) {
      o.yaw = start.yaw + t;
    } else {  // a circle through the start, as far as the limits allow
      o.yaw = start.yaw + 0.5 * (std::cos(t) - 1.0);
      o.pitch = start.pitch + 0.5 * std::sin(t);
    }
    out.push_back(clamp_offset(o, kind));
  }
  return out;
}

}  // namespace stylerf::scene
