#include "lib/scene/capture_geometry.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "host/error.hpp"
#include "lib/scene/llff_loader.hpp"

namespace stylerf::scene {

using host::Error;

namespace {

constexpr double kForwardFacingMaxAngle = 30.0;  // fern 9.5, horns 14.1; the object captures 73..121
constexpr double kBoundFactor = 0.75;            // LLFF's bd_factor: nearest bound -> 1 / 0.75
constexpr double kAssumedNear = 3.0, kAssumedFar = 20.0;  // x RMS camera spread, when there are no bounds

}  // namespace

std::string fmt_number(double v, int precision) {
  std::ostringstream s;
  s.precision(precision);
  s << v;
  return s.str();
}

namespace {

// The depth bounds of the content, over every camera: all cameras have them, or none (then known = false).
struct DepthBounds {
  bool known = false;
  double min_near = 0, max_far = 0;
};

DepthBounds check_bounds(const std::vector<CaptureView>& views, const std::string& what) {
  const int n = int(views.size());
  int with_bounds = 0;
  for (int i = 0; i < n; ++i) {
    const CaptureView& v = views[i];
    if (v.near == 0 && v.far == 0) continue;
    if (!(v.near > 0 && v.far > v.near && std::isfinite(v.far)))
      throw Error(what + ": camera " + std::to_string(i) + " has bounds near " + fmt_number(v.near) + ", far " + fmt_number(v.far) +
                  " (need 0 < near < far)");
    ++with_bounds;
  }
  if (with_bounds != 0 && with_bounds != n)
    throw Error(what + ": " + std::to_string(n - with_bounds) + " of " + std::to_string(n) +
                " cameras have no depth bounds (every camera needs them, or none)");
  DepthBounds b;
  b.known = with_bounds == n;
  if (b.known) {
    b.min_near = views[0].near, b.max_far = views[0].far;
    for (const CaptureView& v : views) b.min_near = std::min(b.min_near, v.near), b.max_far = std::max(b.max_far, v.far);
  }
  return b;
}

void set_ndc_box(Scene& s) {
  s.near = 0.0f;
  s.far = 1.0f;
  const float box[2][3] = {{-1.5f, -1.67f, -1.0f}, {1.5f, 1.67f, 1.0f}};
  std::copy(&box[0][0], &box[0][0] + 6, &s.aabb[0][0]);
}

// Without bounds, a forward-facing capture's content is assumed between 3x and 20x the cameras' RMS spread.
DepthBounds assume_forward_bounds(const std::vector<CaptureView>& views, Scene& s, const std::string& what) {
  const double n = double(views.size());
  Vec3 mean{0, 0, 0};
  for (const CaptureView& v : views) mean = add(mean, scale(v.pose.axis(3), 1.0 / n));
  double ms = 0;
  for (const CaptureView& v : views) ms += std::pow(norm(sub(v.pose.axis(3), mean)), 2) / n;
  const double rms = std::sqrt(ms);
  if (!(rms > 0)) throw Error(what + ": every camera is at the same position, and there are no depth bounds to scale by");
  s.notes.push_back("no depth bounds in the files: nearest content assumed at " + fmt_number(kAssumedNear) + "x and farthest at " +
                    fmt_number(kAssumedFar) + "x the RMS camera spread (" + fmt_number(rms) + ")");
  return {true, kAssumedNear * rms, kAssumedFar * rms};
}

// World-space rays of a forward-facing capture: the box holds every camera frustum between the bounds
// (capped at 4x the nearest bound, where a forward-facing capture has little parallax left).
void set_frustum_box(const std::vector<CaptureView>& views, Scene& s) {
  s.near = float(s.depth_near * 0.9);
  s.far = float(std::min<double>(s.depth_far, 4.0 * s.depth_near));
  for (int k = 0; k < 3; ++k) s.aabb[0][k] = 1e30f, s.aabb[1][k] = -1e30f;
  double widest = 1.0;
  for (const CaptureView& v : views) {
    const Pose& p = v.pose;
    widest = std::max(widest, 1.0 + v.tan_x * v.tan_x + v.tan_y * v.tan_y);
    for (double depth : {double(s.near), double(s.far)})
      for (int cy = -1; cy <= 1; cy += 2)
        for (int cx = -1; cx <= 1; cx += 2) {
          const Vec3 d_cam{cx * v.tan_x, cy * v.tan_y, -1.0};
          for (int k = 0; k < 3; ++k) {
            const double val = p.m[k][3] + depth * (p.m[k][0] * d_cam[0] + p.m[k][1] * d_cam[1] + p.m[k][2] * d_cam[2]);
            s.aabb[0][k] = std::min(s.aabb[0][k], float(val));
            s.aabb[1][k] = std::max(s.aabb[1][k], float(val));
          }
        }
  }
  s.far = float(s.far * std::sqrt(widest));
}

// LLFF's normalisation: rescale so the nearest content sits at 1/0.75 (the NDC near plane z = -1 is then
// in front of it), and express the poses relative to their average.
void normalise_forward_facing(std::vector<CaptureView>& views, DepthBounds b, Scene& s, const std::string& what) {
  const int n = int(views.size());
  if (!b.known) b = assume_forward_bounds(views, s, what);
  const double sc = 1.0 / (b.min_near * kBoundFactor);
  std::vector<Pose> poses(n);
  for (int i = 0; i < n; ++i) {
    poses[i] = views[i].pose;
    for (int r = 0; r < 3; ++r) poses[i].m[r][3] *= sc;
  }
  const Pose avg = average_pose(poses);
  for (int i = 0; i < n; ++i) views[i].pose = relative(avg, poses[i]);
  s.depth_near = float(b.min_near * sc);
  s.depth_far = float(b.max_far * sc);
  s.ndc_near = 1.0f;
  if (s.effects.ndc)
    set_ndc_box(s);
  else
    set_frustum_box(views, s);
}

// Centre on the point every camera looks at, make the mean camera "up" +z, cameras at mean distance 1.
// Returns the scale applied to world units.
double centre_on_focus(std::vector<CaptureView>& views, const std::vector<Vec3>& view_dirs, Scene& s, const std::string& what) {
  const int n = int(views.size());
  std::vector<Vec3> origins(n);
  for (int i = 0; i < n; ++i) origins[i] = views[i].pose.axis(3);
  const Vec3 focus = nearest_point_to_lines(origins, view_dirs);
  int in_front = 0;
  for (int i = 0; i < n; ++i) in_front += dot(sub(focus, origins[i]), view_dirs[i]) > 0;
  if (in_front * 2 < n)
    s.notes.push_back("warning: the common focus point lies behind " + std::to_string(n - in_front) +
                      " cameras; this may not be an object-centric capture (try --ndc on)");
  Vec3 up{0, 0, 0}, front{0, 0, 0};
  double mean_dist = 0;
  for (int i = 0; i < n; ++i) {
    up = add(up, views[i].pose.axis(1));
    front = add(front, sub(origins[i], focus));
    mean_dist += norm(sub(origins[i], focus)) / n;
  }
  if (!(mean_dist > 0) || !std::isfinite(mean_dist))
    throw Error(what + ": the cameras do not surround a point (mean distance to the focus point " + fmt_number(mean_dist) + ")");
  const Vec3 z = normalize(up);
  Vec3 x = sub(front, scale(z, dot(front, z)));
  if (norm(x) < 1e-9 * (1 + norm(front))) x = std::fabs(z[0]) < 0.9 ? Vec3{1, 0, 0} : Vec3{0, 1, 0};
  x = normalize(sub(x, scale(z, dot(x, z))));
  const Vec3 y = cross(z, x);
  const Vec3 rows[3] = {x, y, z};
  const double sc = 1.0 / mean_dist;
  for (CaptureView& v : views) {
    Pose q;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) q.m[r][c] = dot(rows[r], v.pose.axis(c));
      q.m[r][3] = dot(rows[r], sub(v.pose.axis(3), focus)) * sc;
    }
    v.pose = q;
  }
  return sc;
}

// Where an object capture's surroundings are, for the background shell: the median distance from the
// centre of the farthest content each camera sees (its far bound along its axis), so a room's walls and
// table edge, not the object. At least 1.25x the farthest camera and the box's corner, so that every
// camera and the whole box are inside the sphere and each ray leaves it once. Without depth bounds: 3x
// the farthest camera.
double surroundings_radius(const std::vector<CaptureView>& views, const DepthBounds& b, double sc, double half,
                           double max_dist) {
  const double inside = 1.25 * std::max(max_dist, half * std::sqrt(3.0));
  if (!b.known) return std::max(3.0 * max_dist, inside);
  std::vector<double> reach;
  for (const CaptureView& v : views) {
    if (!(v.far > 0)) continue;
    const Vec3 far_point = add(v.pose.axis(3), scale(v.pose.axis(2), -v.far * sc));
    reach.push_back(norm(far_point));
  }
  if (reach.empty()) return std::max(3.0 * max_dist, inside);
  std::sort(reach.begin(), reach.end());
  return std::max(reach[reach.size() / 2], inside);
}

void normalise_object_centric(std::vector<CaptureView>& views, const std::vector<Vec3>& view_dirs, const DepthBounds& b,
                              Scene& s, const std::string& what) {
  const int n = int(views.size());
  const double sc = centre_on_focus(views, view_dirs, s, what);
  double half = 0;
  double min_dist = 1e300, max_dist = 0;
  for (const CaptureView& v : views) {
    min_dist = std::min(min_dist, norm(v.pose.axis(3)));
    max_dist = std::max(max_dist, norm(v.pose.axis(3)));
  }
  if (b.known) {
    // The content nearest to each camera is at distance near_i, so the object reaches at least
    // dist_i - near_i from the centre; the median over cameras (robust to a close table edge) with a
    // margin sizes the box, capped inside the camera sphere.
    std::vector<double> reach(n);
    for (int i = 0; i < n; ++i) reach[i] = norm(views[i].pose.axis(3)) - views[i].near * sc;
    std::sort(reach.begin(), reach.end());
    const double median = reach[n / 2];
    half = std::clamp(1.5 * median, 0.1, 0.9);
    s.notes.push_back("object box: half-size " + fmt_number(half) + " (median reach of the near bounds " + fmt_number(median) +
                      ", x1.5), cameras at mean distance 1 from the focus point");
    s.depth_near = float(b.min_near * sc);
    s.depth_far = float(b.max_far * sc);
  } else {
    half = std::clamp(0.5 * min_dist, 0.1, 0.9);
    s.notes.push_back("object box: half-size " + fmt_number(half) + " (no depth bounds in the files: half the nearest camera's distance " +
                      fmt_number(min_dist) + " from the focus point), cameras at mean distance 1 from it");
    s.depth_near = float(std::max(0.05, min_dist - half * std::sqrt(3.0)));
    s.depth_far = float(max_dist + half * std::sqrt(3.0));
  }
  for (int k = 0; k < 3; ++k) s.aabb[0][k] = float(-half), s.aabb[1][k] = float(half);
  s.shell_radius = float(surroundings_radius(views, b, sc, half, max_dist));
  s.near = float(std::max(0.05, std::min(s.depth_near * 0.9, 1.0 - half * std::sqrt(3.0))));
  s.far = float(max_dist + half * std::sqrt(3.0));
  if (s.effects.ndc) {
    set_ndc_box(s);
    s.ndc_near = float(s.depth_near);
  }
}

}  // namespace

void normalise_capture(std::vector<CaptureView>& views, const std::string& kind, const LoadOptions& opts, Scene& s,
                       const std::string& what) {
  const int n = int(views.size());
  if (n < 2) throw Error(what + ": needs at least 2 cameras, has " + std::to_string(n));
  const DepthBounds bounds = check_bounds(views, what);

  // Forward-facing or object-centric, from the spread of the viewing directions.
  std::vector<Vec3> view_dirs(n);
  for (int i = 0; i < n; ++i) view_dirs[i] = scale(views[i].pose.axis(2), -1.0);
  const double spread = max_view_angle_degrees(view_dirs);
  const bool forward = spread < kForwardFacingMaxAngle;
  s.format = kind + (forward ? "-forward" : "-object");
  s.notes.push_back(std::string(forward ? "forward-facing" : "object-centric") + " capture: viewing directions lie within " +
                    fmt_number(spread) + " degrees of their mean (forward-facing below " + fmt_number(kForwardFacingMaxAngle) + ")");
  s.effects.ndc = opts.ndc == Switch::automatic ? forward : opts.ndc == Switch::on;
  if (opts.ndc != Switch::automatic) s.notes.push_back(std::string("NDC forced ") + (s.effects.ndc ? "on" : "off") + " by --ndc");

  if (forward)
    normalise_forward_facing(views, bounds, s, what);
  else
    normalise_object_centric(views, view_dirs, bounds, s, what);
}

}  // namespace stylerf::scene
