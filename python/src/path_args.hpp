// Paths and scenes as arguments: a path is a str or any os.PathLike (pathlib.Path), read through os.fspath;
// a scene is a Scene already opened or the folder to open. Every entry point that takes one goes through
// these, so an empty path is refused alike everywhere, naming the argument.
#pragma once
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <variant>

#include "lib/scene/scene_meta.hpp"
#include "python/src/handles.hpp"

namespace stylerf::py {

// The path's text; a ValueError "arg: ..." when it is empty ("" is no way to say "none": that is None).
std::string path_arg(const std::filesystem::path& p, const char* arg);

// Scene.open: the folder at `downsample` (None: the scene's default resolution). Takes the library lock.
std::shared_ptr<SceneHandle> open_scene(const std::filesystem::path& dir, std::optional<int> downsample);

// A Scene, or a folder opened as Scene.open(folder) opens it.
using SceneArg = std::variant<std::shared_ptr<SceneHandle>, std::filesystem::path>;
std::shared_ptr<SceneHandle> scene_of(const SceneArg& arg, const char* name);

// What opens a checkpoint's scene when the caller names one: its folder (a Scene's folder and downsample),
// checked against the checkpoint by scene::open_scene_for; none: the scene the checkpoint records.
scene::SceneOverrides scene_overrides(const std::optional<SceneArg>& arg, const char* name);

}  // namespace stylerf::py
