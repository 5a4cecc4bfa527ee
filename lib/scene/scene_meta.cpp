#include "lib/scene/scene_meta.hpp"

#include <filesystem>

#include "host/error.hpp"

namespace stylerf::scene {

using host::Error;
using nlohmann::json;


json scene_meta(const std::string& dir, const LoadOptions& opt, const Scene& s) {
  std::error_code ec;
  const auto abs = std::filesystem::absolute(dir, ec);
  return json{{"dir", ec ? dir : abs.string()},
              {"name", s.name},
              {"format", s.format},
              {"downsample", opt.downsample},
              {"ndc", s.effects.ndc},
              {"view_dependence", s.effects.view_dependence}};
}

std::string scene_dir_from_meta(const json& meta) {
  if (!meta.contains("dir")) throw Error("checkpoint has no scene directory; pass --scene DIR");
  return meta.at("dir").get<std::string>();
}

LoadOptions load_options_from_meta(const json& meta) {
  LoadOptions o;
  o.downsample = meta.value("downsample", 1);
  o.ndc = meta.value("ndc", false) ? Switch::on : Switch::off;
  o.view_dependence = meta.value("view_dependence", false);
  return o;
}

}  // namespace stylerf::scene

namespace stylerf::scene {
void check_same_scene(const nlohmann::json& meta, const Scene& scene, int downsample, const std::string& checkpoint) {
  const std::string name = meta.value("name", ""), format = meta.value("format", "");
  const int ds = meta.value("downsample", 0);
  if (name != scene.name || format != scene.format || ds != downsample)
    throw host::Error("checkpoint " + checkpoint + " was trained on scene '" + name + "' (" + format + ", downsample " +
                      std::to_string(ds) + "), not on '" + scene.name + "' (" + scene.format + ", downsample " +
                      std::to_string(downsample) + ") from " + scene.root);
}

void check_scene_dir_format(const nlohmann::json& meta, const std::string& dir, const std::string& checkpoint) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const bool blender = fs::exists(fs::path(dir) / "transforms_train.json", ec);
  const bool llff = fs::exists(fs::path(dir) / "poses_bounds.npy", ec);
  if (!blender && !llff) return;  // the loader names what is missing
  const std::string format = meta.value("format", ""), name = meta.value("name", "");
  if (format.empty()) return;
  const bool want_blender = format == "blender";
  if (want_blender != blender || (!want_blender && !llff))
    throw host::Error("checkpoint " + checkpoint + " was trained on scene '" + name + "' (" + format + "), but " + dir +
                      " is " + (blender ? "a Blender-format scene" : "an LLFF capture"));
}

CheckpointScene open_scene_for(const nlohmann::json& meta, const std::string& checkpoint,
                               const SceneOverrides& overrides) {
  CheckpointScene out;
  out.options = load_options_from_meta(meta);
  if (overrides.downsample > 0) out.options.downsample = overrides.downsample;
  out.options.load_images = overrides.load_images;
  out.options.log = overrides.log;
  out.dir = overrides.dir.empty() ? scene_dir_from_meta(meta) : overrides.dir;
  if (!meta.empty()) check_scene_dir_format(meta, out.dir, checkpoint);
  out.scene = load_scene(out.dir, out.options);
  if (!meta.empty()) check_same_scene(meta, out.scene, out.options.downsample, checkpoint);
  return out;
}

}  // namespace stylerf::scene
