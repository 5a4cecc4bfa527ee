// stylerf render --ckpt CKPT --views test|path [--frames N] [-o DIR]: renders a density-stage checkpoint
// (RGB) or a feature-stage checkpoint (decoded RGB, plus a PCA picture of the feature map).
//   test: every held-out view -> test_NNN.png, depth/test_NNN_depth.exr (depth along the ray, ray-space units),
//         test_NNN_depth.png (colourised), [test_NNN_features.png], metrics.json (PSNR and SSIM per view
//         and their means);
//   path: a camera path (spiral for forward-facing scenes, orbit for object scenes) -> frame_NNNN.png,
//         depth/depth_NNNN.exr, depth_NNNN.png, [features_NNNN.png], and video.mp4 when ffmpeg is on PATH.
//   --camera-path FILE: the same outputs along the cameras of a nerfstudio camera_path.json (at its render
//         size, the video at its fps); --export-camera-path FILE writes the built-in path in that format
//         and renders nothing (lib/scene/camera_path_json.hpp).
// Feature checkpoints: depth and the PCA picture are at the feature map's resolution (1/4 for the fast
// profile); one PCA, fitted to the first frame, colours every frame.
// Every file is written atomically (temporary file + rename); rays go through the renderer in chunks.
#include <algorithm>
#include <boost/program_options.hpp>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <nlohmann/json.hpp>

#include "examples/stylerf/cli_checks.hpp"
#include "examples/stylerf/commands.hpp"
#include "examples/stylerf/help.hpp"
#include "examples/stylerf/frame_outputs.hpp"
#include "examples/stylerf/rank_outputs.hpp"
#include "host/dist.hpp"
#include "host/error.hpp"
#include "host/files.hpp"
#include "lib/eval/feature_pca.hpp"
#include "lib/eval/metrics.hpp"
#include "lib/io/exr.hpp"
#include "lib/io/image.hpp"
#include "lib/scene/camera_path.hpp"
#include "lib/scene/camera_path_json.hpp"
#include "lib/model/density_model.hpp"
#include "lib/model/feature_model.hpp"
#include "lib/scene/scene_meta.hpp"

namespace po = boost::program_options;
namespace fs = std::filesystem;

namespace {

using stylerf::host::Error;
namespace model = stylerf::model;

stylerf::io::Image to_image(const std::vector<float>& hwc, int w, int h) { return stylerf::cli::interleaved_image(hwc, w, h); }

// What a frame gives, whichever stage rendered it.
struct Frame {
  int width = 0, height = 0;
  std::vector<float> rgb;         // [H][W][3]
  int map_width = 0, map_height = 0;
  std::vector<float> acc, depth;  // [map H][map W]
  std::vector<float> pca;         // [map H][map W][3], feature checkpoints only
};

// Depth as colour: near = yellow, far = dark purple (a few control points of a perceptual ramp, linearly
// interpolated), range from the 2nd..98th percentile of pixels with acc > 0.5; empty pixels black.
stylerf::io::Image colourise_depth(const Frame& r) {
  static const float ramp[5][3] = {{0.99f, 0.91f, 0.14f}, {0.98f, 0.55f, 0.04f}, {0.80f, 0.24f, 0.33f},
                                   {0.42f, 0.07f, 0.51f}, {0.05f, 0.03f, 0.20f}};
  std::vector<float> vals;
  for (size_t i = 0; i < r.depth.size(); ++i)
    if (r.acc[i] > 0.5f) vals.push_back(r.depth[i]);
  float lo = 0, hi = 1;
  if (!vals.empty()) {
    std::sort(vals.begin(), vals.end());
    lo = vals[vals.size() * 2 / 100];
    hi = vals[std::min(vals.size() - 1, vals.size() * 98 / 100)];
  }
  if (!(hi > lo)) hi = lo + 1e-6f;
  stylerf::io::Image img;
  img.width = r.map_width;
  img.height = r.map_height;
  img.data.assign(size_t(3) * r.map_width * r.map_height, 0.0f);
  const size_t plane = size_t(r.map_width) * r.map_height;
  for (size_t i = 0; i < plane; ++i) {
    if (r.acc[i] <= 0.5f) continue;
    const float u = std::clamp((r.depth[i] - lo) / (hi - lo), 0.0f, 1.0f) * 4.0f;
    const int k = std::min(3, int(u));
    const float f = u - k;
    for (int c = 0; c < 3; ++c) img.data[c * plane + i] = ramp[k][c] * (1 - f) + ramp[k + 1][c] * f;
  }
  return img;
}

using stylerf::cli::numbered;

void save_outputs(const Frame& r, const std::string& png, const std::string& exr, const std::string& depth_png,
                  const std::string& pca_png) {
  stylerf::io::save_png(png, to_image(r.rgb, r.width, r.height));
  fs::create_directories(fs::path(exr).parent_path());
  stylerf::io::write_exr(exr, r.depth, r.map_width, r.map_height, 1);
  stylerf::io::save_png(depth_png, colourise_depth(r));
  if (!r.pca.empty()) stylerf::io::save_png(pca_png, to_image(r.pca, r.map_width, r.map_height));
}

// Renders a camera with whichever model the checkpoint holds.
class FrameRenderer {
 public:
  explicit FrameRenderer(const stylerf::io::Checkpoint& ck) : kind_(ck.kind) {
    if (kind_ == "density")
      density_ = std::make_unique<model::DensityModel>(model::load_model(ck));
    else if (kind_ == "features")
      features_ = std::make_unique<model::FeatureModel>(model::FeatureModel::load(ck));
    else
      throw Error("render: checkpoint " + ck.path + " holds a '" + kind_ + "' stage; render takes density or features");
  }
  // Early ray termination for every later render (0: off).
  void set_ert(float threshold) { (density_ ? density_->geo : features_->geo).ert_threshold = threshold; }
  std::string describe() const {
    if (density_) return "density model: " + density_->describe();
    return std::string("feature model (") + model::decoder_profile_name(features_->profile) +
           " profile): " + features_->geo.describe();
  }
  Frame render(const stylerf::scene::Scene& scene, const stylerf::scene::Camera& cam, int chunk) {
    Frame f;
    if (density_) {
      auto r = model::render_view(*density_, scene, cam, chunk);
      f.width = f.map_width = r.width;
      f.height = f.map_height = r.height;
      f.rgb = std::move(r.value);
      f.acc = std::move(r.acc);
      f.depth = std::move(r.depth);
      return f;
    }
    auto r = features_->render_decoded(scene, cam, chunk);
    f.width = r.width;
    f.height = r.height;
    f.rgb = std::move(r.rgb);
    f.map_width = r.map.width;
    f.map_height = r.map.height;
    f.acc = std::move(r.map.acc);
    f.depth = std::move(r.map.depth);
    const int C = int(r.map.features.dim(1)), n = f.map_width * f.map_height;
    const auto rows = stylerf::eval::planar_to_rows(r.map.features.to_host(), C, n);
    if (!pca_) pca_ = std::make_unique<stylerf::eval::FeaturePca>(stylerf::eval::FeaturePca::fit(rows, C));
    f.pca = pca_->apply(rows);
    return f;
  }

 private:
  std::string kind_;
  std::unique_ptr<model::DensityModel> density_;
  std::unique_ptr<model::FeatureModel> features_;
  std::unique_ptr<stylerf::eval::FeaturePca> pca_;
};

// --camera-path FILE, read before any work so that a bad file, or a flag that does not go with it, is
// refused at once (no cameras without the flag).
stylerf::scene::CameraPathFile camera_path_option(const po::variables_map& vm, const std::string& file,
                                                  const std::string& export_path) {
  if (file.empty()) return {};
  if (!export_path.empty()) throw Error("--camera-path and --export-camera-path: give one of them");
  if (vm.count("views") && !vm["views"].defaulted() && vm["views"].as<std::string>() != "path")
    throw Error("--camera-path renders a path: it does not combine with --views " + vm["views"].as<std::string>());
  if (vm.count("frames") && !vm["frames"].defaulted())
    throw Error("--frames does not apply to --camera-path (the file gives the frames)");
  return stylerf::scene::read_camera_path_json(file);
}

// The path outputs along the --camera-path file's cameras (`file` not empty; the video at its fps) or the
// built-in path of `frames` frames: frame_NNNN.png, depth_NNNN.exr / .png, [features_NNNN.png], video.mp4.
void render_path(FrameRenderer& renderer, const stylerf::scene::Scene& scene, const std::string& file,
                 const stylerf::scene::CameraPathFile& from_file, int frames, int chunk, const std::string& out) {
  const bool spiral = scene.effects.ndc || scene.format.find("-forward") != std::string::npos;
  const auto path = file.empty() ? stylerf::scene::default_path(scene, frames) : from_file.cameras;
  const int fps = file.empty() ? 30 : std::max(1, int(std::lround(from_file.fps)));
  std::cout << (file.empty() ? spiral ? "spiral path" : "orbit path" : "camera path " + file) << ", " << path.size()
            << " frames\n";
  // Under mpirun the frames are dealt round robin; rank 0 collects every rank's files and makes the video.
  const std::string mine = stylerf::cli::rank_output_dir(out);
  for (size_t i = 0; i < path.size(); ++i) {
    if (!stylerf::cli::my_view(i)) continue;
    const Frame r = renderer.render(scene, path[i], chunk);
    save_outputs(r, numbered(mine, "frame_", int(i), 4, ".png"), numbered(fs::path(mine) / "depth", "depth_", int(i), 4, ".exr"),
                 numbered(mine, "depth_", int(i), 4, ".png"), numbered(mine, "features_", int(i), 4, ".png"));
    if ((i + 1) % 10 == 0 || i + 1 == path.size()) std::cout << "  frame " << i + 1 << "/" << path.size() << std::endl;
  }
  stylerf::cli::collect_rank_outputs(mine, out);
  if (stylerf::host::Dist::world().root()) stylerf::cli::write_video(out, "frame_%04d.png", "video.mp4", fps, std::cout);
}

// --export-camera-path FILE: the built-in path of `frames` frames in nerfstudio's format. Returns the exit code.
int export_camera_path(const stylerf::scene::Scene& scene, int frames, const std::string& file) {
  stylerf::scene::write_camera_path_json(file, stylerf::scene::default_path(scene, frames));
  std::cout << "camera path (" << frames << " frames, nerfstudio's camera_path.json) -> " << file << "\n";
  return 0;
}

// --views test: the held-out views (max_views of them, evenly spaced) with PSNR and SSIM, metrics.json. Under
// mpirun the views are dealt round robin and rank 0 writes everything.
void render_test_views(FrameRenderer& renderer, const stylerf::scene::Scene& scene, const std::string& ckpt,
                       int max_views, int chunk, const std::string& out) {
  if (scene.test.empty()) throw Error("scene " + scene.root + " has no held-out views; use --views path");
  const int n = static_cast<int>(scene.test.size());
  const int m = max_views > 0 ? std::min(max_views, n) : n;
  nlohmann::json table = nlohmann::json::array();
  double sp = 0, ss = 0, render_s = 0;
  const std::string mine = stylerf::cli::rank_output_dir(out);
  for (int j = 0; j < m; ++j) {
    if (!stylerf::cli::my_view(size_t(j))) continue;
    const int id = static_cast<int>(int64_t(j) * n / m);
    const auto& v = scene.test[size_t(id)];
    const auto t_view = std::chrono::steady_clock::now();
    const Frame r = renderer.render(scene, v.camera, chunk);
    render_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - t_view).count();
    const std::string png = numbered(mine, "test_", id, 3, ".png");
    save_outputs(r, png, numbered(fs::path(mine) / "depth", "test_", id, 3, "_depth.exr"), numbered(mine, "test_", id, 3, "_depth.png"),
                 numbered(mine, "test_", id, 3, "_features.png"));
    const auto a = to_image(r.rgb, r.width, r.height), b = to_image(v.rgb, r.width, r.height);
    const double p = stylerf::eval::psnr(a.data, b.data), s = stylerf::eval::ssim(a, b);
    sp += p;
    ss += s;
    table.push_back({{"view", id}, {"image", fs::path(png).filename().string()}, {"source", v.image_path},
                     {"psnr", p}, {"ssim", s}});
    std::cout << "  view " << id << ": PSNR " << std::fixed << std::setprecision(2) << p << " dB, SSIM "
              << std::setprecision(4) << s << std::endl;
  }
  stylerf::cli::collect_rank_outputs(mine, out);
  table = stylerf::cli::gather_view_rows(table);
  std::vector<double> sums = {sp, ss, render_s};
  stylerf::host::Dist::world().allreduce_sum(sums);
  sp = sums[0];
  ss = sums[1];
  render_s = sums[2];  // the renderer's time summed over the ranks: per view as one process measures it
  if (!stylerf::host::Dist::world().root()) return;
  nlohmann::json doc{{"checkpoint", ckpt},
                     {"scene", scene.root},
                     {"views", table},
                     {"mean_psnr", sp / m},
                     {"mean_ssim", ss / m},
                     // The renderer alone (no files, no metrics): `stylerf run` plans its evaluation by it.
                     {"timing", {{"render_s_per_view", render_s / m}}},
                     {"ssim", "11x11 Gaussian window, sigma 1.5, K1 0.01, K2 0.03, valid filtering"}};
  const std::string jpath = (fs::path(out) / "metrics.json").string();
  stylerf::host::write_file_atomic(jpath, doc.dump(2) + "\n");
  std::cout << "mean PSNR " << std::setprecision(2) << sp / m << " dB, mean SSIM " << std::setprecision(4) << ss / m
            << " over " << m << " views; " << jpath << "\n";
}

int run_render(int argc, char** argv) {
  std::string ckpt, views = "test", out, scene_dir, device, camera_path_file, export_path;
  int frames = 120, chunk = 8192, max_views = 0;
  float ert = -1.0f;
  po::options_description desc("stylerf render --ckpt CKPT --views test|path [options]");
  desc.add_options()("help,h", "show this help")("ckpt", po::value(&ckpt), "density- or feature-stage checkpoint")(
      "views", po::value(&views)->default_value("test"), "test (held-out views + metrics) or path (camera path)")(
      "frames", po::value(&frames)->default_value(120), "frames of the camera path")(
      "camera-path", po::value(&camera_path_file)->value_name("FILE"),
      "render along the cameras of FILE, a nerfstudio camera_path.json, in the scene's world frame (implies the "
      "path outputs: frame_NNNN.png, video.mp4 at the file's fps)")(
      "export-camera-path", po::value(&export_path)->value_name("FILE"),
      "write the scene's built-in camera path (--frames frames) to FILE as a nerfstudio camera_path.json, "
      "then exit without rendering")(
      "output,o", po::value(&out), "output directory (default: <ckpt>_render_<views>)")(
      "scene", po::value(&scene_dir), "scene directory (default: the one the checkpoint was trained on)")(
      "max-views", po::value(&max_views)->default_value(0), "test: render this many evenly spaced views (0: all)")(
      "chunk", po::value(&chunk)->default_value(8192), "rays per renderer call (bounds memory)")(
      "ert", po::value(&ert),
      "early ray termination: stop a ray once its transmittance is below this (0: off; default 1e-4, and off "
      "for NDC scenes, whose rays rarely turn opaque)")(
      "device", po::value(&device), stylerf::cli::kDeviceHelp);
  po::variables_map vm;
  po::store(po::parse_command_line(argc, argv, desc), vm);
  po::notify(vm);
  if (vm.count("help") || ckpt.empty()) {
    stylerf::cli::print_help(std::cout, "render", desc);
    return ckpt.empty() && !vm.count("help") ? 2 : 0;
  }
  if (views != "test" && views != "path") throw Error("--views must be test or path (got '" + views + "')");
  if (frames < 1 || chunk < 1) throw Error("--frames and --chunk must be positive");
  const stylerf::scene::CameraPathFile path_file = camera_path_option(vm, camera_path_file, export_path);
  if (!camera_path_file.empty()) views = "path";
  if (vm.count("ert")) stylerf::cli::check_range("--ert", ert, 0.0, 0.5);
  stylerf::cli::init_runtime(device, false);

  const auto ck = stylerf::io::load_checkpoint(ckpt, "");
  FrameRenderer renderer(ck);
  if (vm.count("ert")) renderer.set_ert(ert);
  const nlohmann::json smeta = ck.meta.value("scene", nlohmann::json::object());
  stylerf::scene::SceneOverrides o;
  o.dir = scene_dir;
  o.load_images = views == "test" && export_path.empty();
  o.log = &std::cout;
  const auto scene = stylerf::scene::open_scene_for(smeta, ckpt, o).scene;
  if (!export_path.empty()) return export_camera_path(scene, frames, export_path);  // nothing rendered
  std::cout << renderer.describe() << "\n";
  if (out.empty()) out = ckpt + "_render_" + views;
  fs::create_directories(out);
  const auto t0 = std::chrono::steady_clock::now();

  if (views == "test") {
    render_test_views(renderer, scene, ckpt, max_views, chunk, out);
  } else {
    render_path(renderer, scene, camera_path_file, path_file, frames, chunk, out);
  }
  std::cout << "rendered in " << std::fixed << std::setprecision(1)
            << std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() << " s -> " << out << "\n";
  return 0;
}

stylerf::cli::Register reg("render", run_render);
}  // namespace
