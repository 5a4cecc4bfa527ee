#include "examples/stylerf/eval_setup.hpp"

#include <chrono>
#include <cmath>
#include <iomanip>
#include <sstream>

#include "examples/stylerf/cli_checks.hpp"
#include "examples/stylerf/refine_option.hpp"
#include "host/error.hpp"
#include "lib/eval/path_frames.hpp"
#include "lib/model/style_model.hpp"
#include "lib/scene/scene_meta.hpp"

namespace stylerf::cli {

using host::Error;

scene::Scene scene_of_checkpoint(const io::Checkpoint& ck, const std::string& dir_arg) {
  scene::SceneOverrides o;
  o.dir = dir_arg;
  o.load_images = false;
  return scene::open_scene_for(ck.meta.value("scene", nlohmann::json::object()), ck.path, o).scene;
}

void check_same_scene_of(const io::Checkpoint& a, const io::Checkpoint& b, const scene::Scene& scene) {
  const nlohmann::json sa = a.meta.value("scene", nlohmann::json::object());
  const nlohmann::json sb = b.meta.value("scene", nlohmann::json::object());
  scene::check_same_scene(sb, scene, scene::load_options_from_meta(sa).downsample, b.path);
}

void check_path_options(PathOptions& p) {
  if (p.frames < 8 || p.frames > 1000)
    throw Error("--scored-frames must be in [8, 1000] (the long range compares frame t with t - 7)");
  if (p.path_frames < p.frames || p.path_frames > 100000)
    throw Error("--path-frames must be in [--scored-frames, 100000] (got " + std::to_string(p.path_frames) + ")");
  if (p.size < 0 || p.size > 4096) throw Error("--size must be in [0, 4096] (0: the scene's)");
  if (!(p.depth_tolerance > 0 && p.depth_tolerance < 1)) throw Error("--depth-tol must be in (0, 1)");
  if (p.chunk < 1) throw Error("--chunk must be >= 1");
  p.supersample = supersample_from(p.supersample_text);
  check_refine_contrast(p.refine_contrast);
}

std::string score_line(const eval::ConsistencyScore& s) {
  std::ostringstream o;
  o << std::fixed << std::setprecision(4);
  auto part = [&](const char* name, const eval::RangeScore& r) {
    o << name << " (k=" << r.k << "): RMSE " << r.rmse;
    if (std::isfinite(r.lpips)) o << " LPIPS " << r.lpips;
    o << " (" << std::setprecision(1) << 100 * r.valid_fraction << "% valid" << std::setprecision(4);
    if (r.skipped) o << ", " << r.skipped << " pairs without a valid pixel";
    o << ")";
  };
  part("short", s.short_range);
  o << "; ";
  part("long", s.long_range);
  return o.str();
}

}  // namespace stylerf::cli
