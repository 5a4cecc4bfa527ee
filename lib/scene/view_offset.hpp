// Interactive cameras: a training view and an offset from it, the way a viewer moves through a scene
// without leaving what the capture saw.
//   - object scenes (Orbit): yaw and pitch (radians) turn the view around the scene's centre (the world
//     origin, the centre orbit_path circles), about the world's up axis +z and then about the horizontal axis
//     through the centre; the elevation stays within +-kMaxElevation; zoom scales the distance by e^-zoom.
//   - forward-facing captures (Forward): yaw, pitch, zoom in [-1, 1] move the camera right, up and forward
//     through the span of the capture's cameras (their 90th-percentile offsets from the mean pose, as the
//     spiral path's radii), turned to keep the point it looked at (at the spiral's focus depth) centred.
// All zero is the training view itself, exactly.
#pragma once
#include <array>

#include "lib/scene/scene.hpp"

namespace stylerf::scene {

enum class ViewKind { Orbit, Forward };
ViewKind view_kind(const Scene& scene);  // Forward for NDC / forward-facing captures (as default_path)
const char* view_kind_name(ViewKind k);  // "orbit" | "forward"

struct ViewOffset {
  int view = 0;  // training view index
  double yaw = 0, pitch = 0, zoom = 0;
};

struct ViewLimits {
  std::array<double, 2> yaw{}, pitch{}, zoom{};
};
constexpr double kMaxElevation = 85.0 * 3.14159265358979323846 / 180.0;
ViewLimits view_limits(ViewKind kind);
// The offset clamped to the limits (the view index is checked, not clamped: out of range is an error).
ViewOffset clamp_offset(const ViewOffset& o, ViewKind kind);

// The camera of an offset from training view o.view, its image `longer` pixels on the longer side (0: the
// view's own size). Throws host::Error when the view index is outside the training views or a value is
// not finite.
Camera offset_camera(const Scene& scene, const ViewOffset& o, int longer = 0);

// `frames` offsets of a recorded orbit starting at `start`: object scenes once around (yaw + 2 pi k / frames),
// forward-facing captures a circle of radius 0.5 in (yaw, pitch) around the start, kept within the limits.
std::vector<ViewOffset> orbit_offsets(const ViewOffset& start, ViewKind kind, int frames);

}  // namespace stylerf::scene
