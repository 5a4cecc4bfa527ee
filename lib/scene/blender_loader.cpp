#include "lib/scene/blender_loader.hpp"

#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "host/error.hpp"
#include "host/files.hpp"
#include "lib/scene/image_files.hpp"

namespace stylerf::scene {

using host::Error;
using nlohmann::json;

namespace {

json read_json(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw Error("Blender scene: " + path + " is missing");
  try {
    return json::parse(host::read_file(path));
  } catch (const json::exception& e) {
    throw Error("Blender scene: " + path + " is not valid JSON: " + e.what());
  }
}

float number(const json& j, const char* key, const std::string& path) {
  if (!j.contains(key) || !j[key].is_number()) throw Error(path + ": '" + key + "' is missing or not a number");
  return j[key].get<float>();
}

// One split: cameras from the JSON, images from the PNGs next to it.
std::vector<View> load_split(const std::string& dir, const std::string& split, const LoadOptions& opts,
                             const std::array<float, 3>& background, bool& any_alpha) {
  namespace fs = std::filesystem;
  const std::string path = (fs::path(dir) / ("transforms_" + split + ".json")).string();
  const json j = read_json(path);
  const float angle_x = number(j, "camera_angle_x", path);
  if (!(angle_x > 0 && angle_x < 3.14159f)) throw Error(path + ": camera_angle_x must be in (0, pi)");
  if (!j.contains("frames") || !j["frames"].is_array() || j["frames"].empty())
    throw Error(path + ": 'frames' is missing or empty");

  std::vector<View> views;
  int ref_w = 0, ref_h = 0;
  std::string ref_path;
  for (size_t i = 0; i < j["frames"].size(); ++i) {
    const json& f = j["frames"][i];
    const std::string what = path + " frame " + std::to_string(i);
    if (!f.contains("file_path") || !f["file_path"].is_string()) throw Error(what + ": 'file_path' is missing");
    std::string rel = f["file_path"].get<std::string>();
    fs::path img = fs::path(dir) / rel;
    if (!img.has_extension()) img += ".png";
    View v;
    v.image_path = img.lexically_normal().string();

    const json& m = f.contains("transform_matrix") ? f["transform_matrix"] : json();
    if (!m.is_array() || m.size() < 3) throw Error(what + ": 'transform_matrix' is missing or not 4x4");
    for (int r = 0; r < 3; ++r) {
      if (!m[r].is_array() || m[r].size() != 4) throw Error(what + ": 'transform_matrix' is not 4x4");
      for (int c = 0; c < 4; ++c) {
        // JSON has no NaN literal; Python's json writes NaN/Infinity, which nlohmann rejects at parse
        // time, and null would land here: treat any non-number as a bad pose.
        if (!m[r][c].is_number()) throw Error(what + ": camera pose entry (row " + std::to_string(r) + ", column " + std::to_string(c) +
                    ") is not a number: " + m[r][c].dump());
        v.camera.c2w[r][c] = m[r][c].get<float>();
      }
    }
    check_pose_finite(v.camera.c2w, what);

    int w = 0, h = 0;
    auto check_size = [&](int iw, int ih) {
      if (ref_w == 0) {
        ref_w = iw, ref_h = ih, ref_path = v.image_path;
      } else if (iw != ref_w || ih != ref_h) {
        throw Error("image " + v.image_path + " is " + std::to_string(iw) + "x" + std::to_string(ih) + " but " +
                    ref_path + " is " + std::to_string(ref_w) + "x" + std::to_string(ref_h) +
                    " (all images of a scene must have one size)");
      }
    };
    if (opts.load_images) {
      RgbaImage im = load_rgba(v.image_path, background);
      w = im.rgb.width;
      h = im.rgb.height;
      check_size(w, h);
      const int nw = std::max(1, w / opts.downsample), nh = std::max(1, h / opts.downsample);
      io::Image rgb = (nw == w && nh == h) ? im.rgb : io::resize(im.rgb, nw, nh);
      v.rgb = interleave(rgb);
      if (!im.alpha.empty()) {
        any_alpha = true;
        v.alpha = (nw == w && nh == h) ? im.alpha : resize_plane(im.alpha, w, h, nw, nh);
      }
    } else {
      image_size(v.image_path, w, h);
      check_size(w, h);
    }
    Camera& c = v.camera;
    c.width = w;
    c.height = h;
    c.fx = 0.5f * w / std::tan(0.5f * angle_x);
    c.fy = j.contains("camera_angle_y") ? 0.5f * h / std::tan(0.5f * number(j, "camera_angle_y", path)) : c.fx;
    c.cx = 0.5f * w;
    c.cy = 0.5f * h;
    c = c.resized(std::max(1, w / opts.downsample), std::max(1, h / opts.downsample));
    views.push_back(std::move(v));
  }
  return views;
}

}  // namespace

Scene load_blender(const std::string& dir, const LoadOptions& opts) {
  namespace fs = std::filesystem;
  Scene s;
  s.root = dir;
  s.name = fs::path(dir).lexically_normal().filename().string();
  if (s.name.empty() || s.name == ".") s.name = fs::absolute(dir).lexically_normal().parent_path().filename().string();
  s.format = "blender";
  s.effects.background_rgb = {1, 1, 1};
  bool any_alpha = false;
  s.train = load_split(dir, "train", opts, s.effects.background_rgb, any_alpha);
  s.test = load_split(dir, "test", opts, s.effects.background_rgb, any_alpha);
  const int w = s.train[0].camera.width, h = s.train[0].camera.height;
  for (const View& v : s.test)
    if (v.camera.width != w || v.camera.height != h)
      throw Error("image " + v.image_path + " is " + std::to_string(v.camera.width) + "x" +
                  std::to_string(v.camera.height) + " but the training images are " + std::to_string(w) + "x" +
                  std::to_string(h) + " (after --downsample)");
  // White background only when the images have alpha to composite; an RGB-only Blender export is taken as is.
  s.effects.background = any_alpha;
  if (!any_alpha) s.notes.push_back("images have no alpha channel: no background colour");
  s.effects.view_dependence = opts.view_dependence;
  s.effects.ndc = false;
  if (opts.ndc == Switch::on) throw host::SettingError("ndc", "on is only meaningful for forward-facing captures, not " + dir);

  s.near = 2.0f;
  s.far = 6.0f;
  const std::string train_json = (fs::path(dir) / "transforms_train.json").string();
  const json j = read_json(train_json);
  if (j.contains("near")) s.near = number(j, "near", train_json);
  if (j.contains("far")) s.far = number(j, "far", train_json);
  if (!(s.near >= 0 && s.far > s.near)) throw Error(train_json + ": need 0 <= near < far");
  if (j.contains("aabb")) {
    const json& a = j["aabb"];
    if (!a.is_array() || a.size() != 2 || !a[0].is_array() || !a[1].is_array() || a[0].size() != 3 || a[1].size() != 3)
      throw Error(train_json + ": 'aabb' must be [[xmin,ymin,zmin],[xmax,ymax,zmax]]");
    for (int k = 0; k < 2; ++k)
      for (int a3 = 0; a3 < 3; ++a3) s.aabb[k][a3] = a[k][a3].get<float>();
    for (int a3 = 0; a3 < 3; ++a3)
      if (!(s.aabb[1][a3] > s.aabb[0][a3])) throw Error(train_json + ": 'aabb' max must exceed min on every axis");
    s.notes.push_back("box, near and far from " + train_json);
  }
  s.depth_near = s.near;
  s.depth_far = s.far;
  return s;
}

}  // namespace stylerf::scene
