// A generated scene (48 px, 20 views) and a short density stage over it, made once per test process: the
// stage-2 and stage-3 suites train on it. Files go to a fresh temporary folder of the process.
#pragma once
#include <filesystem>

#include "lib/model/geometry.hpp"
#include "lib/scene/scene.hpp"

namespace stylerf::testing {

std::filesystem::path small_work_dir();           // temp folder, removed and recreated once per process
const scene::Scene& small_scene();                 // <small_work_dir>/scene
const model::Geometry& small_geometry();          // relu density, 80 iterations, opaque early

}  // namespace stylerf::testing
