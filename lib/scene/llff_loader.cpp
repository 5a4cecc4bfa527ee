#include "lib/scene/llff_loader.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "host/error.hpp"
#include "lib/io/npy.hpp"
#include "lib/scene/image_files.hpp"
#include "lib/scene/poses.hpp"

namespace stylerf::scene {

using host::Error;
namespace fs = std::filesystem;

namespace {

constexpr double kForwardFacingMaxAngle = 30.0;  // fern 9.5, horns 14.1; the object captures 73..121
constexpr double kBoundFactor = 0.75;            // LLFF's bd_factor: nearest bound -> 1 / 0.75
constexpr int kHoldEvery = 8;

std::string fmt(double v) {
  std::ostringstream s;
  s.precision(4);
  s << v;
  return s.str();
}

struct ImageFolder {
  std::string path;
  int factor = 1;  // the folder's own downsample factor (images_M -> M, images -> 1)
};

// images_N when present, else the nearest finer folder, which is then resized.
ImageFolder choose_folder(const std::string& dir, int downsample) {
  std::error_code ec;
  for (int m = downsample; m >= 1; --m) {
    fs::path p = fs::path(dir) / (m == 1 ? std::string("images") : "images_" + std::to_string(m));
    if (fs::is_directory(p, ec)) return {p.string(), m};
  }
  std::string have;
  for (const auto& e : fs::directory_iterator(dir, ec))
    if (e.is_directory(ec) && e.path().filename().string().rfind("images", 0) == 0)
      have += (have.empty() ? "" : ", ") + e.path().filename().string();
  throw Error("LLFF scene " + dir + ": no image folder for --downsample " + std::to_string(downsample) +
              " (looked for images_" + std::to_string(downsample) + " and finer ones down to images/; found: " +
              (have.empty() ? "none" : have) + ")");
}

std::vector<int> test_indices(const std::string& dir, int n, std::vector<std::string>& notes) {
  std::vector<int> ids;
  const fs::path list = fs::path(dir) / "test_img_id.txt";
  std::error_code ec;
  if (fs::exists(list, ec)) {
    std::ifstream in(list);
    int v;
    while (in >> v) {
      if (v < 0 || v >= n)
        throw Error(list.string() + ": test index " + std::to_string(v) + " is outside 0.." + std::to_string(n - 1));
      ids.push_back(v);
    }
    if (!in.eof()) throw Error(list.string() + ": expected whitespace-separated integers");
    std::sort(ids.begin(), ids.end());
    ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
    notes.push_back("test views: the " + std::to_string(ids.size()) + " 0-based indices in " + list.string());
    return ids;
  }
  for (int i = 0; i < n; i += kHoldEvery) ids.push_back(i);
  return ids;
}

Camera to_camera(const Pose& p, float fx, float fy, int w, int h) {
  Camera c;
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 4; ++k) c.c2w[r][k] = float(p.m[r][k]);
  c.fx = fx;
  c.fy = fy;
  c.cx = 0.5f * w;
  c.cy = 0.5f * h;
  c.width = w;
  c.height = h;
  return c;
}

}  // namespace

double max_view_angle_degrees(const std::vector<Vec3>& dirs) {
  Vec3 mean{0, 0, 0};
  for (const Vec3& d : dirs) mean = add(mean, normalize(d));
  mean = normalize(mean);
  double worst = 0;
  for (const Vec3& d : dirs)
    worst = std::max(worst, std::acos(std::clamp(dot(normalize(d), mean), -1.0, 1.0)) * 180.0 / M_PI);
  return worst;
}

namespace {

// poses_bounds.npy: camera-to-world poses (NeRF/OpenGL axes), per-image depth bounds, and the full-size
// images' height, width and focal.
struct LlffPoses {
  std::vector<Pose> poses;
  std::vector<double> near_b, far_b;
  double hwf_h = 0, hwf_w = 0, focal = 0;
};

LlffPoses read_poses_bounds(const std::string& npy) {
  const io::NpyArray a = io::read_npy_checked(npy, {-1, 17}, "poses_bounds");
  const int n = int(a.shape[0]);
  if (n < 2) throw Error(npy + ": needs at least 2 poses, has " + std::to_string(n));
  LlffPoses out;
  out.poses.resize(n);
  out.near_b.resize(n);
  out.far_b.resize(n);
  for (int i = 0; i < n; ++i) {
    const double* row = a.data.data() + size_t(i) * 17;
    for (int k = 0; k < 17; ++k)
      if (!std::isfinite(row[k]))
        throw Error(npy + ": pose " + std::to_string(i) + " has a non-finite entry (element " + std::to_string(k) +
                    " is " + fmt(row[k]) + ")");
    // Stored columns are [down, right, back, position, hwf]; NeRF/OpenGL wants [right, up, back, position].
    for (int r = 0; r < 3; ++r) {
      const double* pr = row + 5 * r;
      out.poses[i].m[r][0] = pr[1];
      out.poses[i].m[r][1] = -pr[0];
      out.poses[i].m[r][2] = pr[2];
      out.poses[i].m[r][3] = pr[3];
    }
    check_pose(out.poses[i].m, npy + ": pose " + std::to_string(i));
    out.near_b[i] = row[15];
    out.far_b[i] = row[16];
    if (!(out.near_b[i] > 0 && out.far_b[i] > out.near_b[i]))
      throw Error(npy + ": pose " + std::to_string(i) + " has bounds near " + fmt(out.near_b[i]) + ", far " +
                  fmt(out.far_b[i]) + " (need 0 < near < far)");
  }
  out.hwf_h = a.data[4], out.hwf_w = a.data[9], out.focal = a.data[14];
  if (!(out.hwf_h > 0 && out.hwf_w > 0 && out.focal > 0))
    throw Error(npy + ": pose 0 has a non-positive height, width or focal");
  return out;
}

// The images matching the poses one to one: their size after --downsample, the intrinsics scaled from
// hwf to it, and (when loaded) their pixels.
struct LlffImages {
  std::vector<std::string> files;
  std::vector<std::vector<float>> rgb;
  int w = 0, h = 0;
  float fx = 0, fy = 0;
};

LlffImages read_llff_images(const std::string& dir, const std::string& npy, const LlffPoses& lp,
                            const LoadOptions& opts, std::vector<std::string>& notes) {
  const int n = int(lp.poses.size());
  const ImageFolder folder = choose_folder(dir, opts.downsample);
  LlffImages out;
  out.files = list_images(folder.path);
  if (int(out.files.size()) != n)
    throw Error("LLFF scene " + dir + ": " + npy + " has " + std::to_string(n) + " poses but " + folder.path + " has " +
                std::to_string(out.files.size()) + " images (they must match one to one, in sorted name order)");
  int src_w = 0, src_h = 0;
  image_size(out.files[0], src_w, src_h);
  out.w = src_w, out.h = src_h;
  if (folder.factor != opts.downsample) {
    out.w = std::max(1, int(std::lround(double(src_w) * folder.factor / opts.downsample)));
    out.h = std::max(1, int(std::lround(double(src_h) * folder.factor / opts.downsample)));
    notes.push_back(folder.path + " resized by " + std::to_string(folder.factor) + "/" +
                    std::to_string(opts.downsample) + " to " + std::to_string(out.w) + "x" + std::to_string(out.h) +
                    " (no images_" + std::to_string(opts.downsample) + ")");
  }
  // Intrinsics follow the images actually used; the aspect ratio must agree with hwf.
  const double sx = out.w / lp.hwf_w, sy = out.h / lp.hwf_h;
  if (std::fabs(sx / sy - 1.0) > 0.02)
    throw Error("LLFF scene " + dir + ": images in " + folder.path + " are " + std::to_string(src_w) + "x" +
                std::to_string(src_h) + " but " + npy + " says " + fmt(lp.hwf_w) + "x" + fmt(lp.hwf_h) +
                " (different aspect ratio: rotated or cropped images?)");
  out.fx = float(lp.focal * sx), out.fy = float(lp.focal * sy);
  out.rgb.resize(n);
  for (int i = 0; i < n; ++i) {
    int iw = 0, ih = 0;
    io::Image img;
    if (opts.load_images) {
      img = io::load_image(out.files[i]);
      iw = img.width, ih = img.height;
    } else {
      image_size(out.files[i], iw, ih);
    }
    if (iw != src_w || ih != src_h)
      throw Error("image " + out.files[i] + " is " + std::to_string(iw) + "x" + std::to_string(ih) + " but " +
                  out.files[0] + " is " + std::to_string(src_w) + "x" + std::to_string(src_h) +
                  " (all images of a scene must have one size)");
    if (opts.load_images) out.rgb[i] = interleave(iw == out.w && ih == out.h ? img : io::resize(img, out.w, out.h));
  }
  return out;
}

// NDC's ray range and TensoRF's box for forward-facing captures.
void use_ndc_box(Scene& s) {
  s.near = 0.0f;
  s.far = 1.0f;
  const float box[2][3] = {{-1.5f, -1.67f, -1.0f}, {1.5f, 1.67f, 1.0f}};
  std::copy(&box[0][0], &box[0][0] + 6, &s.aabb[0][0]);
}

// Forward-facing: rescaled so the nearest content sits at 1/0.75 (the NDC near plane z = -1 is then in
// front of it), recentred on the average pose; without NDC, the box holds every camera frustum between the
// bounds (capped at 4x the nearest bound, where a forward-facing capture has little parallax left).
void arrange_forward_facing(Scene& s, std::vector<Pose>& poses, double min_near, double max_far, int w, int h,
                            float fx, float fy) {
  const double sc = 1.0 / (min_near * kBoundFactor);
  for (Pose& p : poses)
    for (int r = 0; r < 3; ++r) p.m[r][3] *= sc;
  const Pose avg = average_pose(poses);
  for (Pose& p : poses) p = relative(avg, p);
  s.depth_near = float(min_near * sc);
  s.depth_far = float(max_far * sc);
  s.ndc_near = 1.0f;
  if (s.effects.ndc) {
    use_ndc_box(s);
    return;
  }
  s.near = float(s.depth_near * 0.9);
  s.far = float(std::min<double>(s.depth_far, 4.0 * s.depth_near * 1.0));
  for (int k = 0; k < 3; ++k) s.aabb[0][k] = 1e30f, s.aabb[1][k] = -1e30f;
  for (const Pose& p : poses)
    for (double depth : {double(s.near), double(s.far)})
      for (int cy = -1; cy <= 1; cy += 2)
        for (int cx = -1; cx <= 1; cx += 2) {
          Vec3 d_cam{cx * 0.5 * w / fx, cy * 0.5 * h / fy, -1.0};
          for (int k = 0; k < 3; ++k) {
            double v = p.m[k][3] + depth * (p.m[k][0] * d_cam[0] + p.m[k][1] * d_cam[1] + p.m[k][2] * d_cam[2]);
            s.aabb[0][k] = std::min(s.aabb[0][k], float(v));
            s.aabb[1][k] = std::max(s.aabb[1][k], float(v));
          }
        }
  s.far = float(s.far * std::sqrt(1.0 + 0.25 * (w / fx) * (w / fx) + 0.25 * (h / fy) * (h / fy)));
}

// Object-centric: centred on the point every camera looks at, the mean camera "up" made +z, cameras at
// mean distance 1; returns the scale applied.
double centre_object_capture(Scene& s, std::vector<Pose>& poses, const std::vector<Vec3>& view_dirs) {
  const int n = int(poses.size());
  std::vector<Vec3> origins(n);
  for (int i = 0; i < n; ++i) origins[i] = poses[i].axis(3);
  const Vec3 focus = nearest_point_to_lines(origins, view_dirs);
  int in_front = 0;
  for (int i = 0; i < n; ++i) in_front += dot(sub(focus, origins[i]), view_dirs[i]) > 0;
  if (in_front * 2 < n)
    s.notes.push_back("warning: the common focus point lies behind " + std::to_string(n - in_front) +
                      " cameras; this may not be an object-centric capture (try --ndc on)");
  Vec3 up{0, 0, 0}, front{0, 0, 0};
  double mean_dist = 0;
  for (int i = 0; i < n; ++i) {
    up = add(up, poses[i].axis(1));
    front = add(front, sub(origins[i], focus));
    mean_dist += norm(sub(origins[i], focus)) / n;
  }
  const Vec3 z = normalize(up);
  Vec3 x = sub(front, scale(z, dot(front, z)));
  if (norm(x) < 1e-9 * (1 + norm(front))) x = std::fabs(z[0]) < 0.9 ? Vec3{1, 0, 0} : Vec3{0, 1, 0};
  x = normalize(sub(x, scale(z, dot(x, z))));
  const Vec3 y = cross(z, x);
  const Vec3 rows[3] = {x, y, z};
  const double sc = 1.0 / mean_dist;
  for (Pose& p : poses) {
    Pose q;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) q.m[r][c] = dot(rows[r], p.axis(c));
      q.m[r][3] = dot(rows[r], sub(p.axis(3), focus)) * sc;
    }
    p = q;
  }
  return sc;
}

// Object-centric box and ray range. The content nearest to each camera is at distance near_i, so the
// object reaches at least dist_i - near_i from the centre; the median over cameras (robust to a close
// table edge) with a margin sizes the box, capped inside the camera sphere.
void arrange_object_centric(Scene& s, std::vector<Pose>& poses, const std::vector<Vec3>& view_dirs,
                            const std::vector<double>& near_b, double min_near, double max_far) {
  const int n = int(poses.size());
  const double sc = centre_object_capture(s, poses, view_dirs);
  std::vector<double> reach(n);
  for (int i = 0; i < n; ++i) reach[i] = norm(poses[i].axis(3)) - near_b[i] * sc;
  std::sort(reach.begin(), reach.end());
  const double median = reach[n / 2];
  const double half = std::clamp(1.5 * median, 0.1, 0.9);
  for (int k = 0; k < 3; ++k) s.aabb[0][k] = float(-half), s.aabb[1][k] = float(half);
  s.notes.push_back("object box: half-size " + fmt(half) + " (median reach of the near bounds " + fmt(median) +
                    ", x1.5), cameras at mean distance 1 from the focus point");
  s.depth_near = float(min_near * sc);
  s.depth_far = float(max_far * sc);
  s.near = float(std::max(0.05, std::min(s.depth_near * 0.9, 1.0 - half * std::sqrt(3.0))));
  double max_dist = 0;
  for (const Pose& p : poses) max_dist = std::max(max_dist, norm(p.axis(3)));
  s.far = float(max_dist + half * std::sqrt(3.0));
  if (s.effects.ndc) {
    use_ndc_box(s);
    s.ndc_near = float(s.depth_near);
  }
}

}  // namespace

Scene load_llff(const std::string& dir, const LoadOptions& opts) {
  Scene s;
  s.root = dir;
  s.name = fs::path(dir).lexically_normal().filename().string();
  if (s.name.empty() || s.name == ".") s.name = fs::absolute(dir).lexically_normal().parent_path().filename().string();
  s.effects.view_dependence = opts.view_dependence;
  const std::string npy = (fs::path(dir) / "poses_bounds.npy").string();
  LlffPoses lp = read_poses_bounds(npy);
  const int n = int(lp.poses.size());
  LlffImages im = read_llff_images(dir, npy, lp, opts, s.notes);

  // --- geometry: forward-facing or object-centric -------------------------------------------------
  std::vector<Vec3> view_dirs(n);
  for (int i = 0; i < n; ++i) view_dirs[i] = scale(lp.poses[i].axis(2), -1.0);
  const double spread = max_view_angle_degrees(view_dirs);
  const bool forward = spread < kForwardFacingMaxAngle;
  s.format = forward ? "llff-forward" : "llff-object";
  s.notes.push_back(std::string(forward ? "forward-facing" : "object-centric") + " capture: viewing directions lie within " +
                    fmt(spread) + " degrees of their mean (forward-facing below " + fmt(kForwardFacingMaxAngle) + ")");
  s.effects.ndc = opts.ndc == Switch::automatic ? forward : opts.ndc == Switch::on;
  if (opts.ndc != Switch::automatic) s.notes.push_back(std::string("NDC forced ") + (s.effects.ndc ? "on" : "off") + " by --ndc");
  const double min_near = *std::min_element(lp.near_b.begin(), lp.near_b.end());
  const double max_far = *std::max_element(lp.far_b.begin(), lp.far_b.end());
  if (forward)
    arrange_forward_facing(s, lp.poses, min_near, max_far, im.w, im.h, im.fx, im.fy);
  else
    arrange_object_centric(s, lp.poses, view_dirs, lp.near_b, min_near, max_far);

  // --- split ----------------------------------------------------------------------------------------
  const std::vector<int> test = test_indices(dir, n, s.notes);
  for (int i = 0; i < n; ++i) {
    View v;
    v.camera = to_camera(lp.poses[i], im.fx, im.fy, im.w, im.h);
    v.image_path = im.files[i];
    v.rgb = std::move(im.rgb[i]);
    (std::binary_search(test.begin(), test.end(), i) ? s.test : s.train).push_back(std::move(v));
  }
  if (s.train.empty()) throw Error("LLFF scene " + dir + ": every view is a test view; nothing to train on");
  return s;
}

}  // namespace stylerf::scene
