// A generated scene (48 px, 20 views) and a short density stage over it, made once per test process: the
// stage-2 and stage-3 suites train on it. Files go to a fresh temporary folder of the process.
#pragma once
#include <filesystem>
#include <string>

#include "lib/model/geometry.hpp"
#include "lib/scene/scene.hpp"

namespace stylerf::testing {

std::filesystem::path small_work_dir();           // temp folder, removed and recreated once per process
const scene::Scene& small_scene();                 // <small_work_dir>/scene
const model::Geometry& small_geometry();          // relu density, 80 iterations (40 when small_run()), opaque early

// Checkpoint files over small_geometry() for the command-line suites, written once per process: an
// untrained feature stage (rank 8, fast profile) and a style stage over it (untrained stylizer, running
// variance 0.05): the plumbing is under test, not the quality.
struct SmallStageFiles {
  std::string features, style;
};
const SmallStageFiles& small_stage_files();

}  // namespace stylerf::testing
