#include "lib/scene/llff_loader.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "host/error.hpp"
#include "lib/io/npy.hpp"
#include "lib/scene/capture_geometry.hpp"
#include "lib/scene/image_files.hpp"
#include "lib/scene/poses.hpp"

namespace stylerf::scene {

using host::Error;
namespace fs = std::filesystem;

namespace {

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
  throw Error("LLFF scene " + dir + ": no image folder for downsample " + std::to_string(downsample) +
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
  for (int i = 0; i < n; i += kHoldOutEvery) ids.push_back(i);
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
  LlffPoses lp;
  lp.poses.resize(n);
  lp.near_b.resize(n);
  lp.far_b.resize(n);
  std::vector<Pose>& poses = lp.poses;
  std::vector<double>&near_b = lp.near_b, &far_b = lp.far_b;
  for (int i = 0; i < n; ++i) {
    const double* row = a.data.data() + size_t(i) * 17;
    for (int k = 0; k < 17; ++k)
      if (!std::isfinite(row[k]))
        throw Error(npy + ": pose " + std::to_string(i) + " has a non-finite entry (element " + std::to_string(k) +
                    " is " + fmt_number(row[k]) + ")");
    // Stored columns are [down, right, back, position, hwf]; NeRF/OpenGL wants [right, up, back, position].
    for (int r = 0; r < 3; ++r) {
      const double* pr = row + 5 * r;
      poses[i].m[r][0] = pr[1];
      poses[i].m[r][1] = -pr[0];
      poses[i].m[r][2] = pr[2];
      poses[i].m[r][3] = pr[3];
    }
    check_pose(poses[i].m, npy + ": pose " + std::to_string(i));
    near_b[i] = row[15];
    far_b[i] = row[16];
    if (!(near_b[i] > 0 && far_b[i] > near_b[i]))
      throw Error(npy + ": pose " + std::to_string(i) + " has bounds near " + fmt_number(near_b[i]) + ", far " +
                  fmt_number(far_b[i]) + " (need 0 < near < far)");
  }
  lp.hwf_h = a.data[4], lp.hwf_w = a.data[9], lp.focal = a.data[14];
  if (!(lp.hwf_h > 0 && lp.hwf_w > 0 && lp.focal > 0))
    throw Error(npy + ": pose 0 has a non-positive height, width or focal");
  return lp;
}

}  // namespace

Scene load_llff(const std::string& dir, const LoadOptions& opts) {
  Scene s;
  s.root = dir;
  s.name = fs::path(dir).lexically_normal().filename().string();
  if (s.name.empty() || s.name == ".") s.name = fs::absolute(dir).lexically_normal().parent_path().filename().string();
  s.effects.view_dependence = opts.view_dependence;

  // --- poses and bounds -------------------------------------------------------------------------
  const std::string npy = (fs::path(dir) / "poses_bounds.npy").string();
  LlffPoses lp = read_poses_bounds(npy);
  const int n = int(lp.poses.size());
  std::vector<Pose>& poses = lp.poses;
  const std::vector<double>&near_b = lp.near_b, &far_b = lp.far_b;
  const double hwf_h = lp.hwf_h, hwf_w = lp.hwf_w;

  // --- images -----------------------------------------------------------------------------------
  const ImageFolder folder = choose_folder(dir, opts.downsample);
  const std::vector<std::string> files = list_images(folder.path);
  if (int(files.size()) != n)
    throw Error("LLFF scene " + dir + ": " + npy + " has " + std::to_string(n) + " poses but " + folder.path + " has " +
                std::to_string(files.size()) + " images (they must match one to one, in sorted name order)");
  int src_w = 0, src_h = 0;
  image_size(files[0], src_w, src_h);
  int w = src_w, h = src_h;
  if (folder.factor != opts.downsample) {
    w = std::max(1, int(std::lround(double(src_w) * folder.factor / opts.downsample)));
    h = std::max(1, int(std::lround(double(src_h) * folder.factor / opts.downsample)));
    s.notes.push_back(folder.path + " resized by " + std::to_string(folder.factor) + "/" +
                      std::to_string(opts.downsample) + " to " + std::to_string(w) + "x" + std::to_string(h) +
                      " (no images_" + std::to_string(opts.downsample) + ")");
  }
  // Intrinsics follow the images actually used; the aspect ratio must agree with hwf.
  const double sx = w / hwf_w, sy = h / hwf_h;
  if (std::fabs(sx / sy - 1.0) > 0.02)
    throw Error("LLFF scene " + dir + ": images in " + folder.path + " are " + std::to_string(src_w) + "x" +
                std::to_string(src_h) + " but " + npy + " says " + fmt_number(hwf_w) + "x" + fmt_number(hwf_h) +
                " (different aspect ratio: rotated or cropped images?)");
  const float fx = float(lp.focal * sx), fy = float(lp.focal * sy);

  std::vector<Camera> cams(n);
  std::vector<std::vector<float>> rgb(n);
  for (int i = 0; i < n; ++i) {
    int iw = 0, ih = 0;
    io::Image img;
    if (opts.load_images) {
      img = io::load_image(files[i]);
      iw = img.width, ih = img.height;
    } else {
      image_size(files[i], iw, ih);
    }
    if (iw != src_w || ih != src_h)
      throw Error("image " + files[i] + " is " + std::to_string(iw) + "x" + std::to_string(ih) + " but " + files[0] +
                  " is " + std::to_string(src_w) + "x" + std::to_string(src_h) +
                  " (all images of a scene must have one size)");
    if (opts.load_images) rgb[i] = interleave(iw == w && ih == h ? img : io::resize(img, w, h));
  }

  // --- geometry: forward-facing or object-centric (shared with the COLMAP and nerfstudio loaders) ----
  {
    std::vector<CaptureView> cv(n);
    for (int i = 0; i < n; ++i) {
      cv[i].pose = poses[i];
      cv[i].near = near_b[i];
      cv[i].far = far_b[i];
      cv[i].tan_x = 0.5 * w / fx;
      cv[i].tan_y = 0.5 * h / fy;
    }
    normalise_capture(cv, "llff", opts, s, npy);
    for (int i = 0; i < n; ++i) poses[i] = cv[i].pose;
  }

  // --- split ----------------------------------------------------------------------------------------
  const std::vector<int> test = test_indices(dir, n, s.notes);
  for (int i = 0; i < n; ++i) {
    View v;
    v.camera = to_camera(poses[i], fx, fy, w, h);
    v.image_path = files[i];
    v.rgb = std::move(rgb[i]);
    (std::binary_search(test.begin(), test.end(), i) ? s.test : s.train).push_back(std::move(v));
  }
  if (s.train.empty()) throw Error("LLFF scene " + dir + ": every view is a test view; nothing to train on");
  return s;
}

}  // namespace stylerf::scene
