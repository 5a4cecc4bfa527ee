#include "lib/scene/make_scene.hpp"

#include <stb/stb_image_write.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "host/error.hpp"
#include "host/files.hpp"
#include "lib/io/exr.hpp"
#include "lib/scene/analytic_scene.hpp"
#include "lib/scene/poses.hpp"

namespace stylerf::scene {

using host::Error;
namespace fs = std::filesystem;

namespace {

const char* kGenerator = "stylerf make-scene";

// Replacing DIR is allowed only when nothing of value can be lost.
void check_replaceable(const fs::path& dir) {
  std::error_code ec;
  if (!fs::exists(dir, ec)) return;
  if (!fs::is_directory(dir, ec)) throw Error("make-scene: " + dir.string() + " exists and is not a directory");
  if (fs::is_empty(dir, ec)) return;
  const fs::path marker = dir / "transforms_train.json";
  if (fs::exists(marker, ec)) {
    try {
      auto j = nlohmann::json::parse(host::read_file(marker.string()));
      if (j.value("generator", std::string()) == kGenerator) return;
    } catch (const std::exception&) {
    }
  }
  throw Error("make-scene: " + dir.string() +
              " is not empty and was not made by make-scene; refusing to overwrite it (choose another -o)");
}

void write_rgba_png(const std::string& path, const AnalyticView& v, int w, int h) {
  std::vector<unsigned char> px(size_t(4) * w * h);
  for (size_t i = 0; i < size_t(w) * h; ++i) {
    for (int c = 0; c < 3; ++c) px[4 * i + c] = (unsigned char)std::lround(std::clamp(v.rgb[3 * i + c], 0.0f, 1.0f) * 255.0f);
    px[4 * i + 3] = (unsigned char)std::lround(std::clamp(v.alpha[i], 0.0f, 1.0f) * 255.0f);
  }
  if (!stbi_write_png(path.c_str(), w, h, 4, px.data(), w * 4)) throw Error("make-scene: cannot write " + path);
}

}  // namespace

MakeSceneSummary make_scene(const std::string& dir_arg, const MakeSceneOptions& o) {
  const auto start = std::chrono::steady_clock::now();
  if (o.size < 8 || o.size > 4096) throw host::SettingError("size", "must be in 8..4096, got " + std::to_string(o.size));
  // View i goes to val when i % 10 == 0 and to test when i % 10 == 5: 6 views give one of each and 4 to train.
  if (o.views < 6 || o.views > 100000)
    throw host::SettingError("views", "must be in 6..100000 (views 0 and 5 become the val and test splits)");
  if (o.supersample < 1 || o.supersample > 16) throw host::SettingError("supersample", "must be in 1..16");
  if (!(o.camera_angle_x > 0.01f && o.camera_angle_x < 3.1f)) throw Error("make-scene: the field of view must be in (0.01, 3.1) radians");
  if (!(o.radius > 2.5f) || !std::isfinite(o.radius)) throw host::SettingError("radius", "must exceed 2.5 (cameras outside the [-1.5,1.5]^3 box)");
  const fs::path dir = fs::path(dir_arg).lexically_normal();
  check_replaceable(dir);
  const fs::path tmp = dir.string() + ".partial-" + std::to_string(::getpid());
  std::error_code ec;
  fs::remove_all(tmp, ec);

  const AnalyticScene scene = o.textured ? AnalyticScene::textured() : AnalyticScene::objects();
  const float focal = 0.5f * o.size / std::tan(0.5f * o.camera_angle_x);
  nlohmann::json splits[3];  // train, val, test
  const char* names[3] = {"train", "val", "test"};
  MakeSceneSummary sum;
  try {
    for (int k = 0; k < 3; ++k) {
      fs::create_directories(tmp / names[k]);
      splits[k] = {{"camera_angle_x", o.camera_angle_x},
                   {"generator", kGenerator},
                   {"near", std::max(0.1f, o.radius - 2.6f)},
                   {"far", o.radius + 2.6f},
                   {"aabb", {{-1.5, -1.5, -1.5}, {1.5, 1.5, 1.5}}},
                   {"depth", "EXR channel Y: distance along the unit pixel-centre ray, 0 = background"},
                   {"frames", nlohmann::json::array()}};
    }
    const double golden = M_PI * (3.0 - std::sqrt(5.0));
    // The textured content stands on a floor: cameras from 60 to 15 degrees above it see both.
    const double top = o.textured ? 60.0 : 70.0, bottom = o.textured ? 15.0 : -35.0;
    const double z_top = std::sin(top * M_PI / 180.0), z_bottom = std::sin(bottom * M_PI / 180.0);
    for (int i = 0; i < o.views; ++i) {
      const double z = z_top + (z_bottom - z_top) * (i + 0.5) / o.views;
      const double rho = std::sqrt(1.0 - z * z), az = golden * i;
      const Vec3 eye{o.radius * rho * std::cos(az), o.radius * rho * std::sin(az), o.radius * z};
      const Pose pose = look_at(eye, {0, 0, 0}, {0, 0, 1});
      Camera cam;
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c) cam.c2w[r][c] = float(pose.m[r][c]);
      cam.fx = cam.fy = focal;
      cam.cx = cam.cy = 0.5f * o.size;
      cam.width = cam.height = o.size;

      const int k = i % 10 == 0 ? 1 : i % 10 == 5 ? 2 : 0;
      int& count = k == 0 ? sum.train : k == 1 ? sum.val : sum.test;
      const std::string stem = "r_" + std::to_string(count++);
      const AnalyticView v = render_analytic(scene, cam, o.supersample);
      write_rgba_png((tmp / names[k] / (stem + ".png")).string(), v, o.size, o.size);
      io::write_exr((tmp / names[k] / (stem + "_depth.exr")).string(), v.depth, o.size, o.size, 1);

      nlohmann::json m = nlohmann::json::array();
      for (int r = 0; r < 4; ++r) m.push_back(r < 3 ? nlohmann::json{cam.c2w[r][0], cam.c2w[r][1], cam.c2w[r][2], cam.c2w[r][3]}
                                                    : nlohmann::json{0.0, 0.0, 0.0, 1.0});
      splits[k]["frames"].push_back({{"file_path", std::string("./") + names[k] + "/" + stem},
                                     {"depth_path", std::string("./") + names[k] + "/" + stem + "_depth.exr"},
                                     {"transform_matrix", m}});
    }
    for (int k = 0; k < 3; ++k)
      host::write_file_atomic((tmp / ("transforms_" + std::string(names[k]) + ".json")).string(), splits[k].dump(2));
    // Swap the finished scene into place.
    if (fs::exists(dir, ec)) fs::remove_all(dir);
    if (dir.has_parent_path()) fs::create_directories(dir.parent_path());
    fs::rename(tmp, dir);
  } catch (const fs::filesystem_error& e) {
    fs::remove_all(tmp, ec);
    throw Error(std::string("make-scene: cannot write ") + dir.string() + ": " + e.what());
  } catch (...) {
    fs::remove_all(tmp, ec);
    throw;
  }
  sum.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return sum;
}

}  // namespace stylerf::scene
