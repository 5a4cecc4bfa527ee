// Camera paths in nerfstudio's format through the command line, on a generated scene (the built binary):
// `render --export-camera-path` writes the built-in path and renders nothing; rendering (and stylising)
// along that file gives the same frames, byte for byte, as the built-in path; a bad file or a flag that does
// not combine with it is refused before any output is written.
#include <doctest/doctest.h>

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "host/files.hpp"
#include "tests/cli_runner.hpp"
#include "tests/small_scene.hpp"

using namespace stylerf;
namespace fs = std::filesystem;

namespace {

std::string quoted(const fs::path& p) { return "'" + p.string() + "'"; }

std::string fixture(const std::string& name) { return std::string(STYLERF_TEST_FIXTURES) + "/styles/" + name; }

// Every file the built-in run wrote under `stems` is in the other folder with the same bytes.
void check_same_files(const fs::path& a, const fs::path& b, int frames, const std::vector<std::string>& names) {
  for (int i = 0; i < frames; ++i)
    for (const std::string& n : names) {
      char buf[64];
      std::snprintf(buf, sizeof buf, n.c_str(), i);
      CAPTURE(buf);
      REQUIRE(fs::exists(a / buf));
      REQUIRE(fs::exists(b / buf));
      CHECK(host::read_file((a / buf).string()) == host::read_file((b / buf).string()));
    }
}

}  // namespace

TEST_CASE("render: an exported camera path renders the built-in path's frames, byte for byte") {
  const std::string ckpt = testing::small_stage_files().features;
  const fs::path dir = testing::small_work_dir() / "camera_path_render";
  fs::create_directories(dir);
  const fs::path file = dir / "camera_path.json";

  auto r = testing::run_cli("render --ckpt '" + ckpt + "' --frames 4 --export-camera-path " + quoted(file) + " -o " +
                            quoted(dir / "unused"));
  INFO(r.output);
  REQUIRE(r.code == 0);
  CHECK(!fs::exists(dir / "unused"));  // exported, nothing rendered
  const nlohmann::json j = testing::read_json(file);
  CHECK(j["camera_type"] == "perspective");
  CHECK(j["render_width"] == 48);
  CHECK(j["render_height"] == 48);
  CHECK(j["camera_path"].size() == 4);

  r = testing::run_cli("render --ckpt '" + ckpt + "' --views path --frames 4 -o " + quoted(dir / "builtin"));
  INFO(r.output);
  REQUIRE(r.code == 0);
  r = testing::run_cli("render --ckpt '" + ckpt + "' --camera-path " + quoted(file) + " -o " + quoted(dir / "file"));
  INFO(r.output);
  REQUIRE(r.code == 0);
  check_same_files(dir / "builtin", dir / "file", 4,
                   {"frame_%04d.png", "depth/depth_%04d.exr", "depth_%04d.png", "features_%04d.png"});
  CHECK(!fs::exists(dir / "file" / "frame_0004.png"));
}

TEST_CASE("stylize: an exported camera path stylises as the built-in path, byte for byte") {
  const testing::SmallStageFiles& ck = testing::small_stage_files();
  const fs::path dir = testing::small_work_dir() / "camera_path_stylize";
  fs::create_directories(dir);
  const fs::path file = dir / "camera_path.json";
  auto r = testing::run_cli("render --ckpt '" + ck.features + "' --frames 3 --export-camera-path " + quoted(file));
  INFO(r.output);
  REQUIRE(r.code == 0);
  const std::string common = "stylize --ckpt '" + ck.style + "' --style '" + fixture("rgb16.png") +
                             "' --no-losses --cache none ";
  r = testing::run_cli(common + "--views path --frames 3 -o " + quoted(dir / "builtin"));
  INFO(r.output);
  REQUIRE(r.code == 0);
  r = testing::run_cli(common + "--camera-path " + quoted(file) + " -o " + quoted(dir / "file"));
  INFO(r.output);
  REQUIRE(r.code == 0);
  check_same_files(dir / "builtin", dir / "file", 3, {"frame_%04d.png", "depth/depth_%04d.exr"});
  CHECK(testing::read_json(dir / "file" / "metrics.json")["camera_path"] == file.string());
}

TEST_CASE("render and stylize: a bad camera path or a flag beside it is refused before any output") {
  const testing::SmallStageFiles& ck = testing::small_stage_files();
  const fs::path dir = testing::small_work_dir() / "camera_path_bad";
  fs::create_directories(dir);
  const fs::path bad = dir / "wide.json";
  host::write_file_atomic(bad.string(), R"({"render_width": 48, "render_height": 48, "camera_path": [
      {"camera_to_world": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 4, 0, 0, 0, 1], "fov": 200}]})");
  const fs::path out = dir / "out";
  auto expect = [&](const std::string& args, const std::string& needle) {
    CAPTURE(args);
    const auto r = testing::run_cli(args);
    CAPTURE(r.output);
    CHECK(r.code == 1);
    CHECK(r.output.find(needle) != std::string::npos);
    CHECK(!fs::exists(out));
  };
  const std::string render = "render --ckpt '" + ck.features + "' -o " + quoted(out) + " ";
  expect(render + "--camera-path " + quoted(bad), bad.string() + ": camera_path[0]: \"fov\" must be a vertical field");
  expect(render + "--camera-path " + quoted(dir / "absent.json"), (dir / "absent.json").string());
  expect(render + "--camera-path " + quoted(bad) + " --frames 5", "--frames does not apply to --camera-path");
  expect(render + "--camera-path " + quoted(bad) + " --views test", "does not combine with --views test");
  expect(render + "--camera-path " + quoted(bad) + " --export-camera-path " + quoted(dir / "x.json"),
         "give one of them");
  const std::string stylize = "stylize --ckpt '" + ck.style + "' --style '" + fixture("rgb16.png") + "' --cache none -o " +
                              quoted(out) + " ";
  expect(stylize + "--camera-path " + quoted(bad), "\"fov\" must be a vertical field of view in degrees in (0, 180)");
  expect(stylize + "--camera-path " + quoted(bad) + " --frames 5", "--frames does not apply to --camera-path");
  expect(stylize + "--camera-path " + quoted(bad) + " --views test", "does not combine with --views test");
}
