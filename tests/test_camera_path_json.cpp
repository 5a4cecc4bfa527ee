// Camera paths in nerfstudio's camera_path.json format (lib/scene/camera_path_json.hpp): a written path reads
// back bit for bit (the orbit and spiral paths, and cameras with awkward floats, fx != fy, an off-centre
// principal point); nerfstudio's own intrinsics by hand (a 90-degree fov over 800 rows is a 400 px focal
// length, centred); every bad input an error naming the file and what is wrong, and a refused write leaves
// no file.
#include <doctest/doctest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <random>

#include "host/files.hpp"
#include "lib/scene/camera_path.hpp"
#include "lib/scene/camera_path_json.hpp"
#include "lib/scene/poses.hpp"
#include "tests/testing.hpp"

using namespace stylerf;
using namespace stylerf::scene;
namespace fs = std::filesystem;

namespace {

struct TempDir : testing::TempDir {
  explicit TempDir(const std::string& tag) : testing::TempDir("camera_path_json", tag) {}
};

bool has(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

Camera from_pose(const Pose& p, float fx, float fy, float cx, float cy, int w, int h) {
  Camera c;
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 4; ++k) c.c2w[r][k] = float(p.m[r][k]);
  c.fx = fx, c.fy = fy, c.cx = cx, c.cy = cy, c.width = w, c.height = h;
  return c;
}

// Every field the renderer uses, compared as bits.
void check_same_bits(const std::vector<Camera>& got, const std::vector<Camera>& want) {
  REQUIRE(got.size() == want.size());
  for (size_t i = 0; i < got.size(); ++i) {
    CAPTURE(i);
    CHECK(std::memcmp(got[i].c2w, want[i].c2w, sizeof want[i].c2w) == 0);
    CHECK(std::memcmp(&got[i].fx, &want[i].fx, sizeof(float)) == 0);
    CHECK(std::memcmp(&got[i].fy, &want[i].fy, sizeof(float)) == 0);
    CHECK(std::memcmp(&got[i].cx, &want[i].cx, sizeof(float)) == 0);
    CHECK(std::memcmp(&got[i].cy, &want[i].cy, sizeof(float)) == 0);
    CHECK(got[i].width == want[i].width);
    CHECK(got[i].height == want[i].height);
  }
}

std::vector<Camera> round_trip(const std::vector<Camera>& cams, const std::string& file, double fps = 30) {
  write_camera_path_json(file, cams, fps);
  return read_camera_path_json(file).cameras;
}

// A scene with only what the built-in paths read: training cameras around the origin and depth bounds.
Scene ring_scene(const std::string& format) {
  Scene s;
  s.name = "ring";
  s.format = format;
  s.depth_near = 2.0f;
  s.depth_far = 6.0f;
  for (int i = 0; i < 12; ++i) {
    const double a = 0.5 * i, e = 0.3 + 0.05 * i;
    View v;
    v.camera = from_pose(look_at({4 * std::cos(e) * std::cos(a), 4 * std::cos(e) * std::sin(a), 4 * std::sin(e)},
                                 {0, 0, 0}, {0, 0, 1}),
                         111.111f, 111.111f, 40.0f, 30.0f, 80, 60);
    s.train.push_back(v);
  }
  return s;
}

void write_text(const std::string& path, const std::string& text) {
  std::ofstream f(path, std::ios::binary);
  f << text;
}

// One nerfstudio-style frame (identity pose at z = 3), with `fov`.
nlohmann::json plain_frame(double fov = 50) {
  return {{"camera_to_world", {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 3, 0, 0, 0, 1}}, {"fov", fov}, {"aspect", 1.0}};
}

nlohmann::json plain_path() {
  return {{"camera_type", "perspective"}, {"render_width", 64}, {"render_height", 64}, {"fps", 24},
          {"seconds", 1.0 / 24}, {"camera_path", {plain_frame()}}};
}

}  // namespace

TEST_CASE("camera_path.json: the built-in paths and awkward cameras read back bit for bit") {
  TempDir d("round_trip");
  for (const char* format : {"blender", "llff-forward"}) {
    CAPTURE(format);
    const std::vector<Camera> path = default_path(ring_scene(format), 37);
    check_same_bits(round_trip(path, d.str(std::string(format) + ".json")), path);
  }
  // Random rotations, positions over many magnitudes, fx != fy, a principal point off the centre, -0 and a
  // float whose shortest digits are short (0.1).
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<Camera> cams;
  for (int i = 0; i < 50; ++i) {
    const double mag = std::pow(10.0, u(rng) * 6);
    const Vec3 eye{u(rng) * mag, u(rng) * mag, u(rng) * mag};
    Camera c = from_pose(look_at(eye, {u(rng), u(rng), u(rng)}, {0, 0, 1}), 1234.5678f + i, 987.6543f + 0.1f * i,
                         501.37f, 377.01f, 1008, 756);
    cams.push_back(c);
  }
  cams[3].c2w[0][3] = 0.1f;
  cams[4].c2w[1][3] = -0.0f;
  cams[5].c2w[2][3] = std::numeric_limits<float>::denorm_min();
  const auto back = round_trip(cams, d.str("random.json"), 23.976);
  check_same_bits(back, cams);
  CHECK(std::signbit(back[4].c2w[1][3]));
  CHECK(read_camera_path_json(d.str("random.json")).fps == 23.976);

  // Written with the shortest digits that read back: 0.1f appears as 0.1, not as its double expansion.
  const auto j = nlohmann::json::parse(host::read_file(d.str("random.json")));
  CHECK(j["camera_path"][3]["camera_to_world"][3].dump() == "0.1");
  CHECK(j["camera_type"] == "perspective");
  CHECK(j["render_width"] == 1008);
  CHECK(j["render_height"] == 756);
  CHECK(double(j["seconds"]) == doctest::Approx(50 / 23.976));
  CHECK(j["camera_path"][0]["camera_to_world"].size() == 16);
  CHECK(double(j["camera_path"][0]["aspect"]) == doctest::Approx(1008.0 / 756.0));
  // What nerfstudio renders: the vertical fov of fy.
  CHECK(double(j["camera_path"][0]["fov"]) ==
        doctest::Approx(2 * std::atan(0.5 * 756 / double(cams[0].fy)) * 180 / M_PI).epsilon(1e-12));
}

TEST_CASE("camera_path.json: nerfstudio's intrinsics, by hand") {
  TempDir d("by_hand");
  // A 90-degree vertical fov over 800 rows: tan(45) = 1, so f = 800 / 2 = 400 px, centred at (400, 400).
  const std::string file = d.str("ninety.json");
  write_text(file, R"({"render_width": 800, "render_height": 800, "camera_path": [
      {"camera_to_world": [0, 0, 1, 2.5,  1, 0, 0, -1,  0, 1, 0, 0.25,  0, 0, 0, 1], "fov": 90, "aspect": 1}]})");
  const CameraPathFile p = read_camera_path_json(file);
  REQUIRE(p.cameras.size() == 1);
  const Camera& c = p.cameras[0];
  CHECK(c.fy == 400.0f);
  CHECK(c.fx == 400.0f);
  CHECK(c.cx == 400.0f);
  CHECK(c.cy == 400.0f);
  CHECK(c.width == 800);
  CHECK(c.height == 800);
  CHECK(p.fps == 30);  // none in the file
  // Row-major: the translation is entries 3, 7, 11; the camera looks down its -z, here world -x.
  CHECK(c.position() == std::array<float, 3>{2.5f, -1.0f, 0.25f});
  CHECK(c.forward() == std::array<float, 3>{-1.0f, -0.0f, -0.0f});
  CHECK(focal_from_fov(60, 600) == doctest::Approx(300 * std::sqrt(3.0)));
  CHECK(fov_from_focal(400, 800) == doctest::Approx(90));

  // A wide 640x480 path: the fov is vertical, so f follows the height, and the pixels stay square.
  write_text(file, R"({"render_width": 640, "render_height": 480, "camera_path": [
      {"camera_to_world": [1, 0, 0, 0,  0, 1, 0, 0,  0, 0, 1, 0,  0, 0, 0, 1], "fov": 90}]})");
  const Camera w = read_camera_path_json(file).cameras.at(0);
  CHECK(w.fx == 240.0f);
  CHECK(w.fy == 240.0f);
  CHECK(w.cx == 320.0f);
  CHECK(w.cy == 240.0f);

  // Without stylerf_intrinsics (as nerfstudio writes it), an off-centre camera reads back centred with the
  // fy it was written with.
  Camera off = from_pose(look_at({1, 2, 3}, {0, 0, 0}, {0, 0, 1}), 500, 400, 300, 200, 640, 480);
  auto j = nlohmann::json::parse(camera_path_json_text({off}));
  j["camera_path"][0].erase("stylerf_intrinsics");
  write_text(file, j.dump());
  const Camera centred = read_camera_path_json(file).cameras.at(0);
  CHECK(centred.fy == doctest::Approx(400).epsilon(1e-6));
  CHECK(centred.fx == centred.fy);
  CHECK(centred.cx == 320.0f);
  CHECK(centred.cy == 240.0f);
}

TEST_CASE("camera_path.json: each bad input is an error naming the file and the problem") {
  TempDir d("bad");
  const std::string file = d.str("camera_path.json");
  auto expect = [&](const nlohmann::json& doc, const std::string& needle) {
    CAPTURE(needle);
    write_text(file, doc.dump());
    const std::string e = testing::error_of([&] { read_camera_path_json(file); });
    CAPTURE(e);
    CHECK(has(e, file));
    CHECK(has(e, needle));
  };
  // The valid file first: each case below breaks one thing.
  write_text(file, plain_path().dump());
  CHECK(read_camera_path_json(file).cameras.size() == 1);
  CHECK(read_camera_path_json(file).fps == 24);

  nlohmann::json j = plain_path();
  j.erase("render_height");
  expect(j, "\"render_height\" is missing");
  j = plain_path(), j["render_width"] = 0;
  expect(j, "\"render_width\" must be a whole number of pixels in [1, 16384]");
  j = plain_path(), j["render_width"] = 64.5;
  expect(j, "\"render_width\" must be a whole number");
  j = plain_path(), j.erase("camera_path");
  expect(j, "\"camera_path\" is missing");
  j = plain_path(), j["camera_path"] = nlohmann::json::array();
  expect(j, "\"camera_path\" has no frames");
  j = plain_path(), j["camera_path"][0].erase("camera_to_world");
  expect(j, "camera_path[0]: \"camera_to_world\" is missing");
  j = plain_path(), j["camera_path"][0]["camera_to_world"] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 3};
  expect(j, "camera_path[0]: \"camera_to_world\" must be 16 numbers (a 4x4 matrix, row-major); it is 12 entries");
  j = plain_path(), j["camera_path"][0]["camera_to_world"] = {{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 3}, {0, 0, 0, 1}};
  expect(j, "must be 16 numbers");
  j = plain_path(), j["camera_path"][0]["camera_to_world"][5] = nullptr;
  expect(j, "\"camera_to_world\" entry 5 is not a number (it is null)");
  j = plain_path(), j["camera_path"][0]["camera_to_world"][14] = 0.5;
  expect(j, "bottom row [0, 0, 0.5, 1]");
  j = plain_path(), j["camera_path"][0]["camera_to_world"][0] = 2.0;  // a scaled rotation
  expect(j, "not a rigid transform");
  j = plain_path(), j["camera_path"][0]["camera_to_world"][3] = 1e300;  // beyond float's range
  expect(j, "non-finite entry");
  j = plain_path(), j["camera_path"][0].erase("fov");
  expect(j, "camera_path[0]: \"fov\" is missing");
  for (const double fov : {0.0, 180.0, -30.0, 400.0}) {
    j = plain_path(), j["camera_path"][0]["fov"] = fov;
    expect(j, "\"fov\" must be a vertical field of view in degrees in (0, 180)");
  }
  j = plain_path(), j["camera_path"][0]["fov"] = "50";
  expect(j, "\"fov\" is not a number");
  j = plain_path(), j["camera_path"][0]["aspect"] = -1;
  expect(j, "\"aspect\" must be positive");
  j = plain_path(), j["camera_type"] = "fisheye";
  expect(j, "camera_type \"fisheye\" is not supported (only \"perspective\")");
  j = plain_path(), j["fps"] = 0;
  expect(j, "\"fps\" must be positive");
  j = plain_path(), j["camera_path"][1] = plain_frame(), j["camera_path"][1]["camera_to_world"][0] = "x";
  expect(j, "camera_path[1]: \"camera_to_world\" entry 0 is not a number");
  j = plain_path(), j["camera_path"][0]["stylerf_intrinsics"] = {{"fx", 70}, {"fy", 70}, {"cx", 32}, {"cy", 32}};
  expect(j, "\"stylerf_intrinsics\": fy 70 disagrees with \"fov\" 50");
  j = plain_path(), j["camera_path"][0]["stylerf_intrinsics"] = {{"fx", 70}, {"cx", 32}, {"cy", 32}};
  expect(j, "\"stylerf_intrinsics\": \"fy\" is missing");
  expect(nlohmann::json::array({1, 2}), "not a JSON object");

  // Python's json module writes NaN and Infinity, which JSON has no numbers for.
  write_text(file, R"({"render_width": 64, "render_height": 64, "camera_path": [
      {"camera_to_world": [NaN, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 3, 0, 0, 0, 1], "fov": 50}]})");
  std::string e = testing::error_of([&] { read_camera_path_json(file); });
  CHECK(has(e, file));
  CHECK(has(e, "NaN or Infinity"));
  write_text(file, "{\"render_width\": 64,");
  e = testing::error_of([&] { read_camera_path_json(file); });
  CHECK(has(e, file));
  CHECK(has(e, "not valid JSON"));
  e = testing::error_of([&] { read_camera_path_json(d.str("absent.json")); });
  CHECK(has(e, d.str("absent.json")));
}

TEST_CASE("camera_path.json: a refused write leaves no file") {
  TempDir d("write");
  const std::string file = d.str("out.json");
  Camera a = from_pose(look_at({0, -4, 1}, {0, 0, 0}, {0, 0, 1}), 50, 50, 32, 32, 64, 64);
  Camera b = a;
  b.width = 32;
  testing::expect_error([&] { write_camera_path_json(file, {a, b}); }, "camera 1 is 32x64 but camera 0 is 64x64");
  testing::expect_error([&] { write_camera_path_json(file, {}); }, "no cameras to write");
  testing::expect_error([&] { write_camera_path_json(file, {a}, 0); }, "fps must be positive");
  Camera bad = a;
  bad.c2w[1][3] = std::numeric_limits<float>::quiet_NaN();
  testing::expect_error([&] { write_camera_path_json(file, {a, bad}); }, "camera 1");
  CHECK(fs::is_empty(d.path));  // neither the file nor a temporary beside it

  // An existing file is replaced whole, never truncated by a refused write.
  write_camera_path_json(file, {a, a, a});
  const std::string before = host::read_file(file);
  testing::expect_error([&] { write_camera_path_json(file, {a, bad}); }, "camera 1");
  CHECK(host::read_file(file) == before);
}
