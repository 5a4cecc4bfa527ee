#include "lib/scene/colmap_loader.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>

#include "host/error.hpp"
#include "host/files.hpp"
#include "lib/scene/capture_geometry.hpp"
#include "lib/scene/colmap_model.hpp"
#include "lib/scene/image_files.hpp"

namespace stylerf::scene {

using host::Error;
namespace fs = std::filesystem;

namespace {

std::string scene_name(const std::string& dir) {
  std::string n = fs::path(dir).lexically_normal().filename().string();
  if (n.empty() || n == ".") n = fs::absolute(dir).lexically_normal().parent_path().filename().string();
  return n;
}

// One camera as a file describes it, before resizing and normalisation.
struct RawView {
  Pose pose;            // camera-to-world, OpenGL axes
  std::string image;    // full-size image file
  std::string size_of;  // who states the size ("camera 2 in .../cameras.bin")
  double fx = 0, fy = 0, cx = 0, cy = 0;
  int width = 0, height = 0;  // the stated full size
  double near = 0, far = 0;   // depth bounds (0: unknown)
};

// Images (images_N for --downsample N when it sits beside images/, else resized), one size for all,
// intrinsics scaled to the size used, the shared geometry decisions, and the every-8th split.
Scene finish(std::vector<RawView>& raw, const std::string& dir, const std::string& kind, const std::string& what,
             const LoadOptions& opts, Scene s) {
  const int n = int(raw.size());
  const int ds = opts.downsample;
  std::vector<std::vector<float>> rgb(n);
  std::vector<CaptureView> cv(n);
  std::vector<Camera> cams(n);
  std::string resized_note;
  int ref_w = 0, ref_h = 0;
  std::string ref_path;
  for (int i = 0; i < n; ++i) {
    RawView& r = raw[i];
    std::error_code ec;
    if (!fs::is_regular_file(r.image, ec))
      throw Error(what + ": the image file " + r.image + " is missing (listed as " + r.size_of + ")");
    std::string file = r.image;
    bool prescaled = false;
    if (ds > 1 && fs::path(r.image).parent_path().filename() == "images") {
      const fs::path alt = fs::path(r.image).parent_path().parent_path() / ("images_" + std::to_string(ds)) / fs::path(r.image).filename();
      if (fs::is_regular_file(alt, ec)) file = alt.string(), prescaled = true;
    }
    int iw = 0, ih = 0;
    io::Image img;
    if (opts.load_images) {
      img = io::load_image(file);
      iw = img.width, ih = img.height;
    } else {
      image_size(file, iw, ih);
    }
    int tw = 0, th = 0;
    if (prescaled) {
      tw = iw, th = ih;
      if (std::abs(double(iw) * ds - r.width) > ds || std::abs(double(ih) * ds - r.height) > ds)
        throw Error("image " + file + " is " + std::to_string(iw) + "x" + std::to_string(ih) + " but " + r.size_of + " says " +
                    std::to_string(r.width) + "x" + std::to_string(r.height) + " at full size (1/" + std::to_string(ds) +
                    " of it expected in images_" + std::to_string(ds) + ")");
    } else {
      if (iw != r.width || ih != r.height)
        throw Error("image " + file + " is " + std::to_string(iw) + "x" + std::to_string(ih) + " but " + r.size_of + " says " +
                    std::to_string(r.width) + "x" + std::to_string(r.height));
      tw = std::max(1, int(std::lround(double(iw) / ds)));
      th = std::max(1, int(std::lround(double(ih) / ds)));
      if (ds > 1 && resized_note.empty())
        resized_note = "images resized by 1/" + std::to_string(ds) + " (no images_" + std::to_string(ds) + " beside images/)";
    }
    if (i == 0) {
      ref_w = tw, ref_h = th, ref_path = file;
    } else if (tw != ref_w || th != ref_h) {
      throw Error("image " + file + " is " + std::to_string(tw) + "x" + std::to_string(th) + " but " + ref_path + " is " +
                  std::to_string(ref_w) + "x" + std::to_string(ref_h) + (ds > 1 ? " (after --downsample)" : "") +
                  " (all images of a scene must have one size)");
    }
    if (opts.load_images) rgb[i] = interleave(iw == tw && ih == th ? img : io::resize(img, tw, th));
    Camera& c = cams[i];
    const double sx = double(tw) / r.width, sy = double(th) / r.height;
    c.fx = float(r.fx * sx), c.fy = float(r.fy * sy), c.cx = float(r.cx * sx), c.cy = float(r.cy * sy);
    c.width = tw, c.height = th;
    cv[i].pose = r.pose;
    cv[i].near = r.near;
    cv[i].far = r.far;
    cv[i].tan_x = 0.5 * tw / c.fx;
    cv[i].tan_y = 0.5 * th / c.fy;
    r.image = file;
  }
  if (!resized_note.empty()) s.notes.push_back(resized_note);
  normalise_capture(cv, kind, opts, s, what);
  for (int i = 0; i < n; ++i) {
    View v;
    v.camera = cams[i];
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 4; ++b) v.camera.c2w[a][b] = float(cv[i].pose.m[a][b]);
    check_pose_finite(v.camera.c2w, what + ": camera of " + raw[i].image + " after normalisation");
    v.image_path = raw[i].image;
    v.rgb = std::move(rgb[i]);
    (i % kHoldOutEvery == 0 ? s.test : s.train).push_back(std::move(v));
  }
  if (s.train.empty()) throw Error(what + ": " + std::to_string(n) + " image(s) leave nothing to train on (every 8th is a test view)");
  (void)dir;
  return s;
}

// numpy.percentile's linear interpolation over sorted values.
double percentile(const std::vector<double>& sorted, double p) {
  const double at = p / 100.0 * double(sorted.size() - 1);
  const size_t lo = size_t(std::floor(at)), hi = std::min(sorted.size() - 1, lo + 1);
  return sorted[lo] + (sorted[hi] - sorted[lo]) * (at - double(lo));
}

std::string model_file(const std::string& model_dir, const std::string& stem) {
  std::error_code ec;
  const fs::path bin = fs::path(model_dir) / (stem + ".bin");
  return fs::exists(bin, ec) ? bin.string() : (fs::path(model_dir) / (stem + ".txt")).string();
}

}  // namespace

// ------------------------------------------------------------------------------------------------
Scene load_colmap(const std::string& dir, const LoadOptions& opts) {
  Scene s;
  s.root = dir;
  s.name = scene_name(dir);
  s.effects.view_dependence = opts.view_dependence;
  const std::string model_dir = find_colmap_model(dir);
  if (model_dir.empty())
    throw Error("COLMAP scene " + dir + ": no sparse model (looked for sparse/0/cameras.bin|txt and sparse/cameras.bin|txt)");
  const ColmapModel m = read_colmap_model(model_dir);
  const std::string cams_file = model_file(model_dir, "cameras"), imgs_file = model_file(model_dir, "images");
  const std::string what = "COLMAP scene " + dir;
  for (const auto& [id, c] : m.cameras) {
    if (c.is_pinhole()) continue;
    std::string d;
    const std::vector<double> dist = c.distortion();
    for (size_t k = 0; k < dist.size(); ++k) d += (k ? ", " : "") + fmt_number(dist[k], 6);
    throw Error(cams_file + ": camera " + std::to_string(id) + " is " + c.model_name() + " with distortion (" + d +
                "); stylerf's cameras are pinholes. Undistort the images first: colmap image_undistorter --image_path "
                "<your images> --input_path " + model_dir + " --output_path <new scene folder>, then load that folder");
  }
  const fs::path image_dir = fs::path(dir) / "images";
  std::error_code ec;
  if (!fs::is_directory(image_dir, ec)) throw Error(what + ": the image folder " + image_dir.string() + " is missing");

  std::map<uint64_t, const ColmapPoint*> points;
  for (const ColmapPoint& p : m.points) points[p.id] = &p;
  std::vector<const ColmapImage*> order;
  for (const ColmapImage& im : m.images) order.push_back(&im);
  std::sort(order.begin(), order.end(), [](const ColmapImage* a, const ColmapImage* b) { return a->name < b->name; });

  std::vector<RawView> raw(order.size());
  int without_points = 0;
  for (size_t i = 0; i < order.size(); ++i) {
    const ColmapImage& im = *order[i];
    const ColmapCamera& c = m.cameras.at(im.camera_id);
    RawView& r = raw[i];
    const std::string label = imgs_file + ": image " + std::to_string(im.id) + " (" + im.name + ")";
    r.pose = colmap_c2w(im.qvec, im.tvec, label);
    check_pose(r.pose.m, label);
    r.image = (image_dir / im.name).lexically_normal().string();
    r.size_of = "image " + std::to_string(im.id) + " of camera " + std::to_string(c.id) + " in " + cams_file;
    r.fx = c.fx(), r.fy = c.fy(), r.cx = c.cx(), r.cy = c.cy();
    r.width = int(c.width), r.height = int(c.height);
    // LLFF's bounds: depth along the viewing axis of the points this image observes.
    std::vector<double> z;
    const Vec3 pos = r.pose.axis(3), back = r.pose.axis(2);
    for (int64_t id : im.point3d_ids) {
      if (id < 0) continue;
      const ColmapPoint& p = *points.at(uint64_t(id));
      const double d = -dot(sub({p.xyz[0], p.xyz[1], p.xyz[2]}, pos), back);
      if (d > 0) z.push_back(d);
    }
    if (z.empty()) {
      ++without_points;
      continue;
    }
    std::sort(z.begin(), z.end());
    r.near = percentile(z, 0.1);
    r.far = percentile(z, 99.9);
    if (!(r.far > r.near)) r.far = r.near * 1.01;  // one point seen: a thin but valid range
  }
  if (without_points > 0 && without_points < int(raw.size())) {
    double lo = 1e300, hi = 0;
    for (const RawView& r : raw)
      if (r.near > 0) lo = std::min(lo, r.near), hi = std::max(hi, r.far);
    for (RawView& r : raw)
      if (r.near == 0) r.near = lo, r.far = hi;
    s.notes.push_back(std::to_string(without_points) + " image(s) observe no 3D point in front of them: they take the bounds of the whole scene");
  }
  s.notes.push_back("COLMAP model " + model_dir + " (" + (fs::path(cams_file).extension() == ".bin" ? "binary" : "text") + "): " +
                    std::to_string(m.images.size()) + " images, " + std::to_string(m.cameras.size()) + " camera(s), " +
                    std::to_string(m.points.size()) + " 3D points; depth bounds per image from the points it observes (0.1/99.9 percentiles)");
  return finish(raw, dir, "colmap", what, opts, std::move(s));
}

// ------------------------------------------------------------------------------------------------
namespace {

using nlohmann::json;

// A nerfstudio key from the frame, else from the top level; `required` throws when neither has it.
double ns_number(const json& top, const json& f, const char* key, const std::string& where, bool required,
                 double fallback) {
  const json* v = f.contains(key) ? &f[key] : top.contains(key) ? &top[key] : nullptr;
  if (!v) {
    if (required) throw Error(where + ": '" + key + "' is missing (neither in the frame nor at the top level)");
    return fallback;
  }
  if (!v->is_number()) throw Error(where + ": '" + key + "' is not a number: " + v->dump());
  const double d = v->get<double>();
  if (!std::isfinite(d)) throw Error(where + ": '" + key + "' is not finite");
  return d;
}

std::string ns_text(const json& top, const json& f, const char* key) {
  const json* v = f.contains(key) ? &f[key] : top.contains(key) ? &top[key] : nullptr;
  return v && v->is_string() ? v->get<std::string>() : "";
}

// 'applied_transform' (when present) must be a 3x4 or 4x4 array of numbers; it is noted, not applied.
void check_applied_transform(const json& j, const std::string& path, Scene& s) {
  if (!j.contains("applied_transform")) return;
  const json& a = j["applied_transform"];
  bool ok = a.is_array() && (a.size() == 3 || a.size() == 4);
  for (size_t r = 0; ok && r < a.size(); ++r) {
    ok = a[r].is_array() && a[r].size() == 4;
    for (size_t c = 0; ok && c < 4; ++c) ok = a[r][c].is_number();
  }
  if (!ok) throw Error(path + ": 'applied_transform' must be a 3x4 or 4x4 array of numbers");
  s.notes.push_back("applied_transform in " + path + " noted (the frames' transform_matrix already include it)");
}

// The frame's intrinsics (pinhole only: any distortion is refused) and image size.
void read_nerfstudio_intrinsics(const json& top, const json& f, const std::string& where, RawView& r) {
  const std::string model = ns_text(top, f, "camera_model");
  if (!model.empty() && model != "OPENCV" && model != "PINHOLE" && model != "SIMPLE_PINHOLE")
    throw Error(where + ": camera_model " + model + " is not a pinhole model (stylerf reads PINHOLE, or OPENCV with zero "
                "distortion); undistort the images first (e.g. colmap image_undistorter)");
  std::string dist;
  for (const char* k : {"k1", "k2", "k3", "k4", "p1", "p2"}) {
    const double d = ns_number(top, f, k, where, false, 0.0);
    if (d != 0) dist += std::string(dist.empty() ? "" : ", ") + k + " = " + fmt_number(d, 6);
  }
  if (!dist.empty())
    throw Error(where + ": the camera has lens distortion (" + dist + "); stylerf's cameras are pinholes. Undistort the images "
                "first (colmap image_undistorter, or ns-process-data with an undistorting option) and write the "
                "distortion as 0");
  r.fx = ns_number(top, f, "fl_x", where, true, 0);
  r.fy = ns_number(top, f, "fl_y", where, false, r.fx);
  if (!f.contains("w") && !top.contains("w")) {
    int iw = 0, ih = 0;
    std::error_code ec;
    if (!fs::is_regular_file(r.image, ec)) throw Error(where + ": the image file " + r.image + " is missing");
    image_size(r.image, iw, ih);
    r.width = iw, r.height = ih;
  } else {
    const double w = ns_number(top, f, "w", where, true, 0), h = ns_number(top, f, "h", where, true, 0);
    if (!(w >= 1 && h >= 1 && w <= 1e6 && h <= 1e6 && w == std::floor(w) && h == std::floor(h)))
      throw Error(where + ": image size w " + fmt_number(w, 6) + ", h " + fmt_number(h, 6) + " is not a positive whole number of pixels");
    r.width = int(w), r.height = int(h);
  }
  r.cx = ns_number(top, f, "cx", where, false, 0.5 * r.width);
  r.cy = ns_number(top, f, "cy", where, false, 0.5 * r.height);
  if (!(r.fx > 0 && r.fy > 0))
    throw Error(where + ": focal lengths fl_x " + fmt_number(r.fx, 6) + ", fl_y " + fmt_number(r.fy, 6) + " must be positive");
}

// One frame: its image, intrinsics and camera-to-world matrix (OpenGL convention, as ours).
RawView read_nerfstudio_frame(const json& top, const json& f, const std::string& dir, const std::string& where) {
  if (!f.is_object()) throw Error(where + ": expected an object");
  if (!f.contains("file_path") || !f["file_path"].is_string()) throw Error(where + ": 'file_path' is missing");
  RawView r;
  r.image = (fs::path(dir) / f["file_path"].get<std::string>()).lexically_normal().string();
  r.size_of = where + " ('w', 'h')";
  read_nerfstudio_intrinsics(top, f, where, r);
  const json& m = f.contains("transform_matrix") ? f["transform_matrix"] : json();
  if (!m.is_array() || (m.size() != 3 && m.size() != 4)) throw Error(where + ": 'transform_matrix' is missing or not 4x4");
  for (int a = 0; a < 3; ++a) {
    if (!m[a].is_array() || m[a].size() != 4) throw Error(where + ": 'transform_matrix' is not 4x4");
    for (int b = 0; b < 4; ++b) {
      if (!m[a][b].is_number())
        throw Error(where + ": camera pose entry (row " + std::to_string(a) + ", column " + std::to_string(b) +
                    ") is not a number: " + m[a][b].dump());
      r.pose.m[a][b] = m[a][b].get<double>();
    }
  }
  check_pose(r.pose.m, where);
  return r;
}

}  // namespace

Scene load_nerfstudio(const std::string& dir, const LoadOptions& opts) {
  Scene s;
  s.root = dir;
  s.name = scene_name(dir);
  s.effects.view_dependence = opts.view_dependence;
  const std::string path = (fs::path(dir) / "transforms.json").string();
  json j;
  try {
    j = json::parse(host::read_file(path));
  } catch (const json::exception& e) {
    throw Error("nerfstudio scene: " + path + " is not valid JSON: " + e.what());
  }
  if (!j.is_object()) throw Error(path + ": expected a JSON object at the top");
  if (!j.contains("frames") || !j["frames"].is_array() || j["frames"].empty())
    throw Error(path + ": 'frames' is missing or empty");
  check_applied_transform(j, path, s);
  std::vector<RawView> raw;
  const json& frames = j["frames"];
  for (size_t i = 0; i < frames.size(); ++i)
    raw.push_back(read_nerfstudio_frame(j, frames[i], dir, path + " frame " + std::to_string(i)));
  std::stable_sort(raw.begin(), raw.end(), [](const RawView& a, const RawView& b) { return a.image < b.image; });
  for (size_t i = 1; i < raw.size(); ++i)
    if (raw[i].image == raw[i - 1].image) throw Error(path + ": the image " + raw[i].image + " appears in two frames");
  return finish(raw, dir, "nerfstudio", "nerfstudio scene " + path, opts, std::move(s));
}

}  // namespace stylerf::scene
