// The consistency measurement's set-up, shared by `stylerf eval consistency` / `eval table` and the Python
// module: the first frames of the scene's path, their warps found from a geometry (rendered depth and
// both cameras), and LPIPS as the masked distance.
#pragma once
#include <memory>
#include <vector>

#include "lib/eval/consistency.hpp"
#include "lib/eval/lpips.hpp"
#include "lib/model/block_refine.hpp"
#include "lib/model/geometry.hpp"
#include "lib/scene/scene.hpp"

namespace stylerf::eval {

struct PathOptions {
  int frames = 16, path_frames = 120, size = 0, chunk = 8192;
  int supersample = 0;  // StyleRF content rays per block (render_camera_content: n x n or kQuincunx); 0: each checkpoint's
  std::string supersample_text = "0";  // the command line's --supersample, parsed into supersample
  // Blocks refined to those rays only where the map has edges (render_camera_content); 0: every block.
  float refine_contrast = model::kRefineContrast;
  float strength = -1.0f;  // StyleRF's stylisation strength (StyleModel::strength); negative: each checkpoint's
  float depth_tolerance = 0.03f;
};

struct PathSetup {
  std::vector<scene::Camera> cams;
  PathWarps warps;
  double seconds = 0;  // rendering the geometry and finding the correspondences
};
PathSetup path_setup(const model::Geometry& g, const scene::Scene& scene, const PathOptions& p);
// The same from the geometry of frames already rendered for path_cameras(scene, p...) (rgb_frames' own:
// the RGB floor's render marches the same density, so the table need not march it twice: fern at 1008x756,
// ~21 s a frame). `g` is the geometry they were rendered from: its background colour masks empty space, and
// its background shell, where it has one, is the surface of the pixels the box leaves to it
// (add_shell_surface).
PathSetup path_setup(std::vector<FrameGeometry> frames, const model::Geometry& g, const scene::Scene& scene,
                     const PathOptions& p);

// Masked LPIPS as the consistency metric's distance; null when lpips is null.
std::unique_ptr<MaskedDistance> lpips_distance(const Lpips* lpips);

}  // namespace stylerf::eval
