// How a checkpoint finds its scene again: the directory (absolute) and the load options that matter,
// stored as meta["scene"] by every stage.
#pragma once
#include <nlohmann/json.hpp>
#include <string>

#include "lib/scene/scene.hpp"

namespace stylerf::scene {

nlohmann::json scene_meta(const std::string& dir, const LoadOptions& opt, const Scene& s);
std::string scene_dir_from_meta(const nlohmann::json& meta);
LoadOptions load_options_from_meta(const nlohmann::json& meta);

}  // namespace stylerf::scene

namespace stylerf::scene {
// Throws an Error naming `checkpoint` and both scenes when meta (a checkpoint's scene section) was not
// made from `scene` loaded with `downsample`: another name, format or downsample factor.
void check_same_scene(const nlohmann::json& meta, const Scene& scene, int downsample, const std::string& checkpoint);
// Before loading a scene folder given for a checkpoint (--scene): its format (Blender or LLFF, from the
// files present) must be the one the checkpoint was trained on, so a mismatch is reported as such rather
// than as a complaint about load options (--ndc, --downsample) the user never gave.
void check_scene_dir_format(const nlohmann::json& meta, const std::string& dir, const std::string& checkpoint);

// What a caller may change when it opens a checkpoint's scene again.
struct SceneOverrides {
  std::string dir;              // --scene (empty: the folder the checkpoint was trained on)
  int downsample = 0;           // --downsample (0: the checkpoint's)
  bool load_images = true;      // false: cameras only
  std::ostream* log = nullptr;  // where the scene's summary goes (nullptr: silent)
};
// The scene behind a checkpoint, opened with the same checks for every caller: the folder's format
// (check_scene_dir_format), then the scene's name, format and downsample against the checkpoint's
// (check_same_scene). meta: the checkpoint's meta["scene"] (empty: an old checkpoint; then only
// overrides.dir says where, and nothing is checked); checkpoint: its path, for the messages.
struct CheckpointScene {
  Scene scene;
  std::string dir;      // the folder loaded
  LoadOptions options;  // the options it was loaded with
};
CheckpointScene open_scene_for(const nlohmann::json& meta, const std::string& checkpoint,
                               const SceneOverrides& overrides = {});
}  // namespace stylerf::scene
