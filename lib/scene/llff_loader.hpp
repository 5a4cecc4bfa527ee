// LLFF-format scenes: poses_bounds.npy ([N, 17]: a 3x5 camera-to-world pose whose last column is
// (height, width, focal) of the full-size images, then near and far depth bounds) and a folder of
// images whose sorted order matches the poses.
//
// Two kinds of capture share the format, and the loader tells them apart from the data:
// - forward-facing (fern, horns): every camera looks roughly the same way (largest angle between a
//   viewing direction and the mean direction below 30 degrees). Poses are rescaled so the nearest
//   bound is 1/0.75, recentred on the average pose, and rays go to NDC with the near plane at z = -1;
//   box [[-1.5,-1.67,-1],[1.5,1.67,1]] in NDC (TensoRF's).
// - object-centric (cameras around an object): the world is moved so the point nearest to all optical
//   axes is the origin, rotated so the mean camera "up" is +z, and scaled so the cameras sit at a mean
//   distance of 1; no NDC; the box is a cube around the origin sized from the near bounds.
// `--ndc on|off` overrides the NDC decision (the normalisation still follows the geometry).
// Images: images_N for --downsample N; when that folder is missing, the nearest finer folder (images_M
// with M < N, or images/) is resized. Intrinsics are scaled from hwf by the actual image size.
// Test views: every 8th image (0, 8, 16, ...), or the 0-based indices in test_img_id.txt when present.
#pragma once
#include <string>

#include "lib/scene/scene.hpp"

namespace stylerf::scene {

Scene load_llff(const std::string& dir, const LoadOptions& opts);

// Forward-facing test used by the loader: the largest angle (degrees) between any camera's viewing
// direction and their mean direction.
double max_view_angle_degrees(const std::vector<std::array<double, 3>>& view_dirs);

}  // namespace stylerf::scene
