#include "lib/scene/camera_path_json.hpp"

#include <charconv>
#include <cmath>
#include <cstring>
#include <nlohmann/json.hpp>
#include <sstream>

#include "host/error.hpp"
#include "host/files.hpp"

namespace stylerf::scene {

namespace {

using host::Error;
using nlohmann::json;
using nlohmann::ordered_json;

constexpr int kMaxRenderSide = 16384;
// How far the stylerf_intrinsics' fy may be from the fov's (relative): the fov is written from fy in double
// and printed with round-trip digits, so a file written here agrees to about 1e-15.
constexpr double kFocalAgreement = 1e-5;

bool same_bits(float a, float b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// The float as a JSON number: the double of its shortest decimal digits (which the JSON writer prints as
// those digits), when that double converts back to the same float; else the float's exact double value.
// Either way the file reads back to the same float, bit for bit.
ordered_json float_number(float v) {
  char buf[64];
  const auto printed = std::to_chars(buf, buf + sizeof buf, v);
  double d = 0;
  const auto parsed = std::from_chars(buf, printed.ptr, d);
  if (printed.ec == std::errc() && parsed.ec == std::errc() && same_bits(static_cast<float>(d), v)) return d;
  return static_cast<double>(v);
}

std::string show(double v) {
  std::ostringstream s;
  s.precision(9);
  s << v;
  return s.str();
}

// obj[key] as a finite number; `where` names the file and the entry.
double number_at(const json& obj, const std::string& key, const std::string& where) {
  const auto it = obj.find(key);
  if (it == obj.end()) throw Error(where + ": \"" + key + "\" is missing");
  if (!it->is_number()) throw Error(where + ": \"" + key + "\" is not a number (it is " + it->dump() + ")");
  const double v = it->get<double>();
  if (!std::isfinite(v)) throw Error(where + ": \"" + key + "\" is not finite");
  return v;
}

int render_side(const json& top, const std::string& key, const std::string& where) {
  const double v = number_at(top, key, where);
  if (v != std::floor(v) || v < 1 || v > kMaxRenderSide)
    throw Error(where + ": \"" + key + "\" must be a whole number of pixels in [1, " + std::to_string(kMaxRenderSide) +
                "] (it is " + show(v) + ")");
  return static_cast<int>(v);
}

// "camera_to_world": 16 numbers, a row-major 4x4 whose bottom row is 0 0 0 1 and whose top 3x4 is rigid.
void read_pose(const json& cam, const std::string& where, Camera& c) {
  const auto it = cam.find("camera_to_world");
  if (it == cam.end()) throw Error(where + ": \"camera_to_world\" is missing");
  if (!it->is_array() || it->size() != 16)
    throw Error(where + ": \"camera_to_world\" must be 16 numbers (a 4x4 matrix, row-major); it is " +
                (it->is_array() ? std::to_string(it->size()) + " entries" : it->dump()));
  double m[4][4];
  for (int k = 0; k < 16; ++k) {
    const json& e = (*it)[size_t(k)];
    if (!e.is_number())
      throw Error(where + ": \"camera_to_world\" entry " + std::to_string(k) + " is not a number (it is " + e.dump() +
                  ")");
    m[k / 4][k % 4] = e.get<double>();
    if (!std::isfinite(m[k / 4][k % 4]))
      throw Error(where + ": \"camera_to_world\" entry " + std::to_string(k) + " is not finite");
  }
  const double bottom[4] = {0, 0, 0, 1};
  for (int k = 0; k < 4; ++k)
    if (std::abs(m[3][k] - bottom[k]) > 1e-6)
      throw Error(where + ": \"camera_to_world\" has bottom row [" + show(m[3][0]) + ", " + show(m[3][1]) + ", " +
                  show(m[3][2]) + ", " + show(m[3][3]) + "]; a camera-to-world matrix ends with [0, 0, 0, 1]");
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 4; ++k) c.c2w[r][k] = static_cast<float>(m[r][k]);
  check_pose_finite(c.c2w, where + ": \"camera_to_world\"");  // also catches values beyond float's range
}

// fx, fy, cx, cy from "fov" (nerfstudio's: square pixels, centred), or from "stylerf_intrinsics" when the
// file carries them and they agree with the fov.
void read_intrinsics(const json& cam, int width, int height, const std::string& where, Camera& c) {
  const double fov = number_at(cam, "fov", where);
  if (!(fov > 0 && fov < 180))
    throw Error(where + ": \"fov\" must be a vertical field of view in degrees in (0, 180) (it is " + show(fov) + ")");
  if (cam.contains("aspect")) {
    const double aspect = number_at(cam, "aspect", where);
    if (!(aspect > 0)) throw Error(where + ": \"aspect\" must be positive (it is " + show(aspect) + ")");
  }
  const double focal = focal_from_fov(fov, height);
  c.fx = c.fy = static_cast<float>(focal);
  c.cx = 0.5f * static_cast<float>(width);
  c.cy = 0.5f * static_cast<float>(height);
  const auto it = cam.find("stylerf_intrinsics");
  if (it == cam.end()) return;
  const std::string inner = where + ": \"stylerf_intrinsics\"";
  if (!it->is_object()) throw Error(inner + " must be an object with fx, fy, cx, cy (it is " + it->dump() + ")");
  const double fx = number_at(*it, "fx", inner), fy = number_at(*it, "fy", inner);
  const double cx = number_at(*it, "cx", inner), cy = number_at(*it, "cy", inner);
  if (!(fx > 0 && fy > 0)) throw Error(inner + ": fx and fy must be positive");
  if (std::abs(fy - focal) > kFocalAgreement * focal)
    throw Error(inner + ": fy " + show(fy) + " disagrees with \"fov\" " + show(fov) + " (which gives fy " +
                show(focal) + " at height " + std::to_string(height) +
                "); the fov was changed without them: remove \"stylerf_intrinsics\" to render the fov");
  c.fx = static_cast<float>(fx);
  c.fy = static_cast<float>(fy);
  c.cx = static_cast<float>(cx);
  c.cy = static_cast<float>(cy);
}

void check_writable(const std::vector<Camera>& cameras, double fps) {
  if (cameras.empty()) throw Error("camera path: no cameras to write");
  if (!(fps > 0) || !std::isfinite(fps)) throw Error("camera path: fps must be positive (it is " + show(fps) + ")");
  const Camera& first = cameras.front();
  for (size_t i = 0; i < cameras.size(); ++i) {
    const Camera& c = cameras[i];
    const std::string what = "camera path: camera " + std::to_string(i);
    if (c.width != first.width || c.height != first.height)
      throw Error(what + " is " + std::to_string(c.width) + "x" + std::to_string(c.height) + " but camera 0 is " +
                  std::to_string(first.width) + "x" + std::to_string(first.height) +
                  " (a camera_path.json has one render size)");
    if (c.width < 1 || c.height < 1 || c.width > kMaxRenderSide || c.height > kMaxRenderSide)
      throw Error(what + ": image size " + std::to_string(c.width) + "x" + std::to_string(c.height) + " is out of range");
    if (!(c.fx > 0 && c.fy > 0) || !std::isfinite(c.fx) || !std::isfinite(c.fy) || !std::isfinite(c.cx) ||
        !std::isfinite(c.cy))
      throw Error(what + ": intrinsics must be finite with positive focal lengths");
    check_pose_finite(c.c2w, what);
  }
}

}  // namespace

double focal_from_fov(double fov_degrees, int height) {
  return 0.5 * height / std::tan(0.5 * fov_degrees * M_PI / 180.0);
}

double fov_from_focal(double focal, int height) { return 2.0 * std::atan(0.5 * height / focal) * 180.0 / M_PI; }

CameraPathFile read_camera_path_json(const std::string& path) {
  const std::string what = "camera path " + path;
  const std::string text = host::read_file(path);
  json top;
  try {
    top = json::parse(text);
  } catch (const json::exception& e) {
    const bool non_finite = text.find("NaN") != std::string::npos || text.find("Infinity") != std::string::npos;
    throw Error(what + ": not valid JSON" +
                (non_finite ? " (it holds NaN or Infinity, which are not JSON numbers: a value is not finite)" : "") +
                ": " + e.what());
  }
  if (!top.is_object())
    throw Error(what + ": not a JSON object (a camera_path.json has render_width, render_height and camera_path)");
  if (const auto t = top.find("camera_type"); t != top.end()) {
    if (!t->is_string()) throw Error(what + ": \"camera_type\" is not a string (it is " + t->dump() + ")");
    if (t->get<std::string>() != "perspective")
      throw Error(what + ": camera_type \"" + t->get<std::string>() + "\" is not supported (only \"perspective\")");
  }
  const int width = render_side(top, "render_width", what), height = render_side(top, "render_height", what);
  CameraPathFile out;
  if (top.contains("fps")) {
    out.fps = number_at(top, "fps", what);
    if (!(out.fps > 0)) throw Error(what + ": \"fps\" must be positive (it is " + show(out.fps) + ")");
  }
  const auto list = top.find("camera_path");
  if (list == top.end()) throw Error(what + ": \"camera_path\" is missing (the list of frames' cameras)");
  if (!list->is_array()) throw Error(what + ": \"camera_path\" is not a list");
  if (list->empty()) throw Error(what + ": \"camera_path\" has no frames");
  for (size_t i = 0; i < list->size(); ++i) {
    const json& cam = (*list)[i];
    const std::string where = what + ": camera_path[" + std::to_string(i) + "]";
    if (!cam.is_object()) throw Error(where + " is not an object");
    Camera c;
    c.width = width;
    c.height = height;
    read_pose(cam, where, c);
    read_intrinsics(cam, width, height, where, c);
    out.cameras.push_back(c);
  }
  return out;
}

std::string camera_path_json_text(const std::vector<Camera>& cameras, double fps) {
  check_writable(cameras, fps);
  const int width = cameras.front().width, height = cameras.front().height;
  ordered_json frames = ordered_json::array();
  for (const Camera& c : cameras) {
    ordered_json m = ordered_json::array();
    for (int r = 0; r < 3; ++r)
      for (int k = 0; k < 4; ++k) m.push_back(float_number(c.c2w[r][k]));
    for (const double v : {0.0, 0.0, 0.0, 1.0}) m.push_back(v);
    ordered_json f;
    f["camera_to_world"] = std::move(m);
    f["fov"] = fov_from_focal(double(c.fy), height);
    f["aspect"] = double(width) / double(height);
    f["stylerf_intrinsics"] = {{"fx", float_number(c.fx)},
                               {"fy", float_number(c.fy)},
                               {"cx", float_number(c.cx)},
                               {"cy", float_number(c.cy)}};
    frames.push_back(std::move(f));
  }
  ordered_json top;
  top["camera_type"] = "perspective";
  top["render_width"] = width;
  top["render_height"] = height;
  top["fps"] = fps;
  top["seconds"] = double(cameras.size()) / fps;
  top["camera_path"] = std::move(frames);
  return top.dump(2) + "\n";
}

void write_camera_path_json(const std::string& path, const std::vector<Camera>& cameras, double fps) {
  host::write_file_atomic(path, camera_path_json_text(cameras, fps));
}

}  // namespace stylerf::scene
