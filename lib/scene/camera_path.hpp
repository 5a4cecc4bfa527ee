// Camera paths for rendering videos: a spiral in front of a forward-facing capture (as LLFF/TensoRF:
// around the average pose, radii from the 90th percentile of camera offsets, two turns, focus at the
// weighted harmonic mean of near and far depth) and an orbit around object scenes (around +z through
// the origin, at the training cameras' mean distance and elevation).
#pragma once
#include <vector>

#include "lib/scene/scene.hpp"

namespace stylerf::scene {

// The spiral's focus: the depth it looks at, mostly the near content (LLFF's weighted harmonic mean of
// 0.9 x the near and 5 x the far depth, 3 : 1 in inverse depth); 1 where the scene has no depth bounds.
double path_focus_depth(const Scene& scene);

std::vector<Camera> spiral_path(const Scene& scene, int frames = 120);
std::vector<Camera> orbit_path(const Scene& scene, int frames = 120);
// spiral for NDC / forward-facing scenes, orbit otherwise.
std::vector<Camera> default_path(const Scene& scene, int frames = 120);

}  // namespace stylerf::scene
