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
}  // namespace stylerf::scene
