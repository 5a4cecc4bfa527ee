// What `stylerf eval consistency` and `stylerf eval table` share: a checkpoint's scene found again (cameras
// only), the path's warps from a geometry, and LPIPS as the masked distance.
#pragma once
#include <memory>
#include <string>

#include "lib/eval/consistency.hpp"
#include "lib/eval/lpips.hpp"
#include "lib/io/checkpoint.hpp"
#include "lib/model/geometry.hpp"
#include "lib/scene/scene.hpp"

namespace stylerf::cli {

// The checkpoint's scene, cameras only (no images), from `dir` or the folder the checkpoint records.
scene::Scene scene_of_checkpoint(const io::Checkpoint& ck, const std::string& dir = "");
// Throws unless the two checkpoints were trained on the same scene at the same downsample.
void check_same_scene_of(const io::Checkpoint& a, const io::Checkpoint& b, const scene::Scene& scene);

struct PathOptions {
  int frames = 16, path_frames = 120, size = 0, chunk = 8192;
  int supersample = 0;  // StyleRF content rays per block and axis (render_camera_content); 0: each checkpoint's
  float depth_tolerance = 0.03f;
};
// Also the options' ranges, checked before anything loads.
void check_path_options(const PathOptions& p);

struct PathSetup {
  std::vector<scene::Camera> cams;
  eval::PathWarps warps;
  double seconds = 0;  // rendering the geometry and finding the correspondences
};
PathSetup path_setup(const model::Geometry& g, const scene::Scene& scene, const PathOptions& p);

// Masked LPIPS (VGG) as the consistency metric's distance; null when lpips is null.
std::unique_ptr<eval::MaskedDistance> lpips_distance(const eval::Lpips* lpips);

// One line: "short (k=1): RMSE x LPIPS y; long (k=7): ...; valid pixels a% / b%".
std::string score_line(const eval::ConsistencyScore& s);

}  // namespace stylerf::cli
