// NeRF-synthetic (Blender) scenes: transforms_{train,test}.json with camera_angle_x and per-frame
// transform_matrix (camera-to-world, OpenGL axes), RGBA PNGs composited over white.
// Defaults as TensoRF: near 2, far 6, box [-1.5, 1.5]^3. Optional keys our generator writes and this
// loader honours: "near", "far", "aabb" ([[x,y,z],[x,y,z]]), "camera_angle_y".
#pragma once
#include <string>

#include "lib/scene/scene.hpp"

namespace stylerf::scene {

Scene load_blender(const std::string& dir, const LoadOptions& opts);

}  // namespace stylerf::scene
