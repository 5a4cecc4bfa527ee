#include "python/src/path_args.hpp"

namespace stylerf::py {

std::string path_arg(const std::filesystem::path& p, const char* arg) {
  if (p.empty()) throw pyb::value_error(std::string(arg) + ": an empty path; give a file or folder name");
  return p.string();
}

std::shared_ptr<SceneHandle> open_scene(const std::filesystem::path& dir, std::optional<int> downsample) {
  if (downsample && (*downsample < 1 || *downsample > 64))
    throw pyb::value_error("downsample: must be in [1, 64], or None for the scene's default (got " +
                           std::to_string(*downsample) + ")");
  auto h = std::make_shared<SceneHandle>();
  h->dir = path_arg(dir, "path");
  LibraryCall call;
  h->options.downsample = scene::resolve_downsample(h->dir, downsample.value_or(0));
  h->scene = scene::load_scene(h->dir, h->options);
  return h;
}

std::shared_ptr<SceneHandle> scene_of(const SceneArg& arg, const char* name) {
  if (const auto* h = std::get_if<std::shared_ptr<SceneHandle>>(&arg)) {
    if (!*h) throw pyb::value_error(std::string(name) + ": give a Scene or a scene folder");
    return *h;
  }
  const auto& dir = std::get<std::filesystem::path>(arg);
  path_arg(dir, name);
  return open_scene(dir, std::nullopt);
}

scene::SceneOverrides scene_overrides(const std::optional<SceneArg>& arg, const char* name) {
  scene::SceneOverrides o;
  if (!arg) return o;
  if (const auto* h = std::get_if<std::shared_ptr<SceneHandle>>(&*arg)) {
    if (!*h) return o;
    o.dir = (*h)->dir;
    o.downsample = (*h)->options.downsample;
  } else {
    o.dir = path_arg(std::get<std::filesystem::path>(*arg), name);
  }
  return o;
}

}  // namespace stylerf::py
