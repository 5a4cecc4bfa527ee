// What `stylerf eval consistency` and `stylerf eval table` share: a checkpoint's scene found again (cameras
// only), the path's warps from a geometry, and LPIPS as the masked distance.
#pragma once
#include <memory>
#include <string>

#include "lib/eval/consistency.hpp"
#include "lib/eval/path_consistency.hpp"
#include "lib/eval/lpips.hpp"
#include "lib/io/checkpoint.hpp"
#include "lib/model/geometry.hpp"
#include "lib/scene/scene.hpp"

namespace stylerf::cli {

// The checkpoint's scene, cameras only (no images), from `dir` or the folder the checkpoint records.
scene::Scene scene_of_checkpoint(const io::Checkpoint& ck, const std::string& dir = "");
// Throws unless the two checkpoints were trained on the same scene at the same downsample.
void check_same_scene_of(const io::Checkpoint& a, const io::Checkpoint& b, const scene::Scene& scene);

using eval::PathOptions;  // lib/eval/path_consistency.hpp
using eval::PathSetup;
using eval::path_setup;
using eval::lpips_distance;

// Also the options' ranges, checked before anything loads.
void check_path_options(PathOptions& p);

// One line: "short (k=1): RMSE x LPIPS y; long (k=7): ...; valid pixels a% / b%".
std::string score_line(const eval::ConsistencyScore& s);

}  // namespace stylerf::cli
