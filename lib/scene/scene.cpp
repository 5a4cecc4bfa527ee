#include "lib/scene/scene.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <ostream>
#include <sstream>

#include "host/error.hpp"
#include "lib/scene/blender_loader.hpp"
#include "lib/scene/colmap_loader.hpp"
#include "lib/scene/colmap_model.hpp"
#include "lib/scene/image_files.hpp"
#include "lib/scene/llff_loader.hpp"
#include "lib/scene/masked_background.hpp"

namespace stylerf::scene {

using host::Error;

Camera Camera::resized(int new_width, int new_height) const {
  Camera c = *this;
  const float sx = float(new_width) / width, sy = float(new_height) / height;
  c.fx *= sx;
  c.cx *= sx;
  c.fy *= sy;
  c.cy *= sy;
  c.width = new_width;
  c.height = new_height;
  return c;
}

Camera Camera::with_longer_side(int size) const {
  if (size <= 0) return *this;
  const bool wide = width >= height;
  const int w = wide ? size : std::max(1, int(std::lround(double(size) * width / height)));
  const int h = wide ? std::max(1, int(std::lround(double(size) * height / width))) : size;
  return resized(w, h);
}

bool Camera::project(const std::array<float, 3>& p, float& px, float& py) const {
  // cam = R^T (p - t); R's columns are the camera axes in world space.
  float d[3] = {p[0] - c2w[0][3], p[1] - c2w[1][3], p[2] - c2w[2][3]};
  float cam[3];
  for (int a = 0; a < 3; ++a) cam[a] = c2w[0][a] * d[0] + c2w[1][a] * d[1] + c2w[2][a] * d[2];
  if (cam[2] >= 0) return false;
  px = cx + fx * cam[0] / -cam[2];
  py = cy - fy * cam[1] / -cam[2];
  return true;
}

void check_pose(const double c2w[3][4], const std::string& what) {
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c)
      if (!std::isfinite(c2w[r][c]))
        throw Error(what + ": camera pose has a non-finite entry (row " + std::to_string(r) + ", column " +
                    std::to_string(c) + " is " + std::to_string(c2w[r][c]) + ")");
  // The rotation must be orthonormal with determinant +1 (a rigid camera): an all-zero or scaled matrix
  // would give NaN or skewed rays. 1e-3 allows the rounding of poses stored as text.
  double worst = 0;
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b) {
      double d = 0;
      for (int r = 0; r < 3; ++r) d += c2w[r][a] * c2w[r][b];
      worst = std::max(worst, std::abs(d - (a == b ? 1.0 : 0.0)));
    }
  const double det = c2w[0][0] * (c2w[1][1] * c2w[2][2] - c2w[1][2] * c2w[2][1]) -
                     c2w[0][1] * (c2w[1][0] * c2w[2][2] - c2w[1][2] * c2w[2][0]) +
                     c2w[0][2] * (c2w[1][0] * c2w[2][1] - c2w[1][1] * c2w[2][0]);
  if (worst > 1e-3 || det < 0.5) {
    std::ostringstream o;
    o << what << ": camera pose is not a rigid transform (its rotation part has |R^T R - I| = " << worst
      << " and det " << det << "; a camera-to-world matrix needs an orthonormal rotation with det +1)";
    throw Error(o.str());
  }
}

void check_pose_finite(const float c2w[3][4], const std::string& what) {
  double m[3][4];
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) m[r][c] = c2w[r][c];
  check_pose(m, what);
}

std::string Scene::describe() const {
  std::ostringstream s;
  s << std::setprecision(4);
  s << "scene " << name << " (" << format << ") from " << root << "\n";
  s << "  views: " << train.size() << " train, " << test.size() << " test, " << width() << "x" << height();
  if (!train.empty()) {
    const Camera& c = train[0].camera;
    s << ", fx " << c.fx << " fy " << c.fy << " cx " << c.cx << " cy " << c.cy;
  }
  s << "\n  rays: near " << near << " far " << far << (effects.ndc ? " (NDC parameter)" : " (world units)")
    << "; box [" << aabb[0][0] << ", " << aabb[0][1] << ", " << aabb[0][2] << "] .. [" << aabb[1][0] << ", "
    << aabb[1][1] << ", " << aabb[1][2] << "]" << (effects.ndc ? " in NDC" : "") << "\n";
  s << "  effects on:";
  bool any = false;
  if (effects.ndc) {
    s << " NDC rays (forward-facing; NDC near plane z = -" << ndc_near << ")";
    any = true;
  }
  if (effects.background) {
    s << (any ? "," : "") << " background colour (" << effects.background_rgb[0] << ", " << effects.background_rgb[1]
      << ", " << effects.background_rgb[2] << ") (" << effects.background_reason << ")";
    any = true;
  }
  if (effects.background_shell) {
    s << (any ? "," : "") << " background shell (radius " << shell_radius << ")";
    any = true;
  }
  if (effects.view_dependence) {
    s << (any ? "," : "") << " view-dependent colour";
    any = true;
  }
  if (!any) s << " none";
  s << "\n";
  for (const auto& n : notes) s << "  note: " << n << "\n";
  return s.str();
}

int resolve_downsample(const std::string& dir, int requested) {
  if (requested > 0) return requested;
  if (requested < 0)
    throw host::SettingError("downsample", "must be at least 1, or 0 for the scene's default (got " +
                                               std::to_string(requested) + ")");
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::exists(fs::path(dir) / "poses_bounds.npy", ec)) return 1;
  // LLFF: the paper's 1/4 is 1008x756 of 4032x3024 captures. Captures of smaller images (object captures at
  // 544x960 or 1140x855) keep the factor that brings their longer side to at most kLlffLongestSide, so a
  // 960-pixel capture trains at its own size rather than at 240.
  const fs::path images = fs::path(dir) / "images";
  const std::vector<std::string> files = fs::is_directory(images, ec) ? list_images(images.string()) : std::vector<std::string>{};
  if (files.empty()) return 4;
  int w = 0, h = 0;
  image_size(files.front(), w, h);
  int factor = 1;
  while (std::max(w, h) > kLlffLongestSide * factor) factor *= 2;
  return factor;
}

Scene load_scene(const std::string& dir, const LoadOptions& opts) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw Error("scene directory " + dir + " does not exist");
  if (opts.downsample < 1)
    throw host::SettingError("downsample", "must be at least 1 (got " + std::to_string(opts.downsample) + ")");
  Scene s;
  if (fs::exists(fs::path(dir) / "transforms_train.json", ec)) {
    s = load_blender(dir, opts);
  } else if (fs::exists(fs::path(dir) / "poses_bounds.npy", ec)) {
    s = load_llff(dir, opts);
  } else if (fs::exists(fs::path(dir) / "transforms.json", ec)) {
    s = load_nerfstudio(dir, opts);
  } else if (!find_colmap_model(dir).empty()) {
    s = load_colmap(dir, opts);
  } else if (fs::exists(fs::path(dir) / "transforms_test.json", ec) || fs::exists(fs::path(dir) / "transforms_val.json", ec)) {
    throw Error("Blender scene: " + (fs::path(dir) / "transforms_train.json").string() + " is missing");
  } else {
    throw Error("scene directory " + dir +
                " has none of transforms_train.json (Blender format), poses_bounds.npy (LLFF format), transforms.json "
                "(nerfstudio) or sparse/0/cameras.bin|txt (COLMAP, with images/)");
  }
  detect_plain_background(s);
  if (opts.log) *opts.log << s.describe() << std::flush;
  return s;
}

Switch parse_switch(const std::string& value, const std::string& flag) {
  if (value == "auto") return Switch::automatic;
  if (value == "on") return Switch::on;
  if (value == "off") return Switch::off;
  throw host::Error(flag + " must be auto, on or off (got '" + value + "')");
}

}  // namespace stylerf::scene
