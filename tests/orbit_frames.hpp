// Frames of the generated analytic scene from an orbit, with their exact geometry: what the warp tests
// (test_consistency) compares views of.
#pragma once
#include <cmath>
#include <vector>

#include "lib/eval/warp.hpp"
#include "lib/io/image.hpp"
#include "lib/scene/analytic_scene.hpp"
#include "lib/scene/poses.hpp"

namespace stylerf::testing {

constexpr int kOrbitSize = 64;

// Camera i of an orbit around the origin, 3 degrees apart (a 120-frame path), slightly above the horizon.
inline scene::Camera orbit_camera(int i, int size = kOrbitSize, double radius = 4.0) {
  const double az = 0.3 + i * (2.0 * M_PI / 120.0);
  const scene::Vec3 eye{radius * std::cos(az) * 0.94, radius * std::sin(az) * 0.94, radius * 0.34};
  const scene::Pose pose = scene::look_at(eye, {0, 0, 0}, {0, 0, 1});
  scene::Camera cam;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) cam.c2w[r][c] = float(pose.m[r][c]);
  cam.fx = cam.fy = 0.5f * size / std::tan(0.45f);
  cam.cx = cam.cy = 0.5f * size;
  cam.width = cam.height = size;
  return cam;
}

struct AnalyticFrame {
  eval::FrameGeometry geo;
  io::Image image;
};

// One supersample: colour, alpha and depth all belong to the pixel-centre ray, so an exact warp of the
// true geometry can only differ by the bilinear resampling of the textures.
inline AnalyticFrame analytic_frame(const scene::Camera& cam) {
  const auto v = scene::render_analytic(scene::AnalyticScene::objects(), cam, 1);
  AnalyticFrame f;
  f.geo.camera = cam;
  f.geo.depth = v.depth;
  f.geo.opacity = v.alpha;
  f.image.width = cam.width;
  f.image.height = cam.height;
  f.image.data.resize(size_t(3) * cam.width * cam.height);
  const size_t plane = size_t(cam.width) * cam.height;
  for (size_t i = 0; i < plane; ++i)
    for (int c = 0; c < 3; ++c)  // over a white background, as Blender scenes are shown
      f.image.data[c * plane + i] = v.rgb[i * 3 + c] * v.alpha[i] + (1.0f - v.alpha[i]);
  return f;
}

// The warp options of an object over a background colour (the analytic scene's frames).
inline eval::WarpOptions object_options() {
  eval::WarpOptions o;
  o.mask_background = true;
  return o;
}

}  // namespace stylerf::testing
