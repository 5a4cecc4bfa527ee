// stylerf render --ckpt CKPT --views test|path [--frames N] [-o DIR]: renders a density-stage checkpoint.
//   test: every held-out view -> test_NNN.png, test_NNN_depth.exr (depth along the ray, ray-space units),
//         test_NNN_depth.png (colourised), metrics.json (PSNR and SSIM per view and their means);
//   path: a camera path (spiral for forward-facing scenes, orbit for object scenes) -> frame_NNNN.png,
//         depth_NNNN.exr / .png, and video.mp4 when ffmpeg is on PATH.
// Every file is written atomically (temporary file + rename); rays go through the renderer in chunks.
#include <boost/program_options.hpp>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <nlohmann/json.hpp>

#include "examples/stylerf/commands.hpp"
#include "host/error.hpp"
#include "host/files.hpp"
#include "lib/eval/metrics.hpp"
#include "lib/io/exr.hpp"
#include "lib/io/image.hpp"
#include "lib/scene/camera_path.hpp"
#include "lib/model/density_model.hpp"
#include "lib/scene/scene_meta.hpp"

namespace po = boost::program_options;
namespace fs = std::filesystem;

namespace {

using stylerf::host::Error;
namespace model = stylerf::model;

stylerf::io::Image to_image(const std::vector<float>& hwc, int w, int h) {
  stylerf::io::Image img;
  img.width = w;
  img.height = h;
  img.data.resize(hwc.size());
  const size_t plane = size_t(w) * h;
  for (size_t i = 0; i < plane; ++i)
    for (int c = 0; c < 3; ++c) img.data[c * plane + i] = hwc[3 * i + c];
  return img;
}

// Depth as colour: near = yellow, far = dark purple (a few control points of a perceptual ramp, linearly
// interpolated), range from the 2nd..98th percentile of pixels with acc > 0.5; empty pixels black.
stylerf::io::Image colourise_depth(const model::ViewValues& r) {
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
  img.width = r.width;
  img.height = r.height;
  img.data.assign(size_t(3) * r.width * r.height, 0.0f);
  const size_t plane = size_t(r.width) * r.height;
  for (size_t i = 0; i < plane; ++i) {
    if (r.acc[i] <= 0.5f) continue;
    const float u = std::clamp((r.depth[i] - lo) / (hi - lo), 0.0f, 1.0f) * 4.0f;
    const int k = std::min(3, int(u));
    const float f = u - k;
    for (int c = 0; c < 3; ++c) img.data[c * plane + i] = ramp[k][c] * (1 - f) + ramp[k + 1][c] * f;
  }
  return img;
}

std::string numbered(const fs::path& dir, const std::string& stem, int i, int digits, const std::string& ext) {
  std::ostringstream o;
  o << stem << std::setw(digits) << std::setfill('0') << i << ext;
  return (dir / o.str()).string();
}

void save_outputs(const model::ViewValues& r, const std::string& png, const std::string& exr,
                  const std::string& depth_png) {
  stylerf::io::save_png(png, to_image(r.value, r.width, r.height));
  stylerf::io::write_exr(exr, r.depth, r.width, r.height, 1);
  stylerf::io::save_png(depth_png, colourise_depth(r));
}

bool have_ffmpeg() { return std::system("command -v ffmpeg >/dev/null 2>&1") == 0; }

int run_render(int argc, char** argv) {
  std::string ckpt, views = "test", out, scene_dir, device;
  int frames = 120, chunk = 8192, max_views = 0;
  po::options_description desc("stylerf render --ckpt CKPT --views test|path [options]");
  desc.add_options()("help,h", "show this help")("ckpt", po::value(&ckpt), "density-stage checkpoint")(
      "views", po::value(&views)->default_value("test"), "test (held-out views + metrics) or path (camera path)")(
      "frames", po::value(&frames)->default_value(120), "frames of the camera path")(
      "output,o", po::value(&out), "output directory (default: <ckpt>_render_<views>)")(
      "scene", po::value(&scene_dir), "scene directory (default: the one the checkpoint was trained on)")(
      "max-views", po::value(&max_views)->default_value(0), "test: render this many evenly spaced views (0: all)")(
      "chunk", po::value(&chunk)->default_value(8192), "rays per renderer call (bounds memory)")(
      "device", po::value(&device), "OpenCL device: index, cpu|gpu|accelerator, or part of a name");
  po::variables_map vm;
  po::store(po::parse_command_line(argc, argv, desc), vm);
  po::notify(vm);
  if (vm.count("help") || ckpt.empty()) {
    std::cout << desc;
    return ckpt.empty() && !vm.count("help") ? 2 : 0;
  }
  if (views != "test" && views != "path") throw Error("--views must be test or path (got '" + views + "')");
  if (frames < 1 || chunk < 1) throw Error("--frames and --chunk must be positive");
  stylerf::cli::init_runtime(device, false);

  const auto ck = stylerf::io::load_checkpoint(ckpt, "density");
  auto density = model::load_model(ck);
  const nlohmann::json smeta = ck.meta.value("scene", nlohmann::json::object());
  if (scene_dir.empty()) scene_dir = stylerf::scene::scene_dir_from_meta(smeta);
  auto lo = stylerf::scene::load_options_from_meta(smeta);
  lo.load_images = views == "test";
  lo.log = &std::cout;
  const auto scene = stylerf::scene::load_scene(scene_dir, lo);
  std::cout << "model: " << density.describe() << "\n";
  if (out.empty()) out = ckpt + "_render_" + views;
  fs::create_directories(out);
  const auto t0 = std::chrono::steady_clock::now();

  if (views == "test") {
    if (scene.test.empty()) throw Error("scene " + scene.root + " has no held-out views; use --views path");
    const int n = static_cast<int>(scene.test.size());
    const int m = max_views > 0 ? std::min(max_views, n) : n;
    nlohmann::json table = nlohmann::json::array();
    double sp = 0, ss = 0;
    for (int j = 0; j < m; ++j) {
      const int id = static_cast<int>(int64_t(j) * n / m);
      const auto& v = scene.test[size_t(id)];
      const auto r = model::render_view(density, scene, v.camera, chunk);
      const std::string png = numbered(out, "test_", id, 3, ".png");
      save_outputs(r, png, numbered(out, "test_", id, 3, "_depth.exr"), numbered(out, "test_", id, 3, "_depth.png"));
      const auto a = to_image(r.value, r.width, r.height), b = to_image(v.rgb, r.width, r.height);
      const double p = stylerf::eval::psnr(a.data, b.data), s = stylerf::eval::ssim(a, b);
      sp += p;
      ss += s;
      table.push_back({{"view", id}, {"image", fs::path(png).filename().string()}, {"source", v.image_path},
                       {"psnr", p}, {"ssim", s}});
      std::cout << "  view " << id << ": PSNR " << std::fixed << std::setprecision(2) << p << " dB, SSIM "
                << std::setprecision(4) << s << std::endl;
    }
    nlohmann::json doc{{"checkpoint", ckpt},
                       {"scene", scene.root},
                       {"views", table},
                       {"mean_psnr", sp / m},
                       {"mean_ssim", ss / m},
                       {"ssim", "11x11 Gaussian window, sigma 1.5, K1 0.01, K2 0.03, valid filtering"}};
    const std::string jpath = (fs::path(out) / "metrics.json").string();
    stylerf::host::write_file_atomic(jpath, doc.dump(2) + "\n");
    std::cout << "mean PSNR " << std::setprecision(2) << sp / m << " dB, mean SSIM " << std::setprecision(4) << ss / m
              << " over " << m << " views; " << jpath << "\n";
  } else {
    const auto path = stylerf::scene::default_path(scene, frames);
    std::cout << (scene.effects.ndc || scene.format == "llff-forward" ? "spiral" : "orbit") << " path, "
              << path.size() << " frames\n";
    for (size_t i = 0; i < path.size(); ++i) {
      const auto r = model::render_view(density, scene, path[i], chunk);
      save_outputs(r, numbered(out, "frame_", int(i), 4, ".png"), numbered(out, "depth_", int(i), 4, ".exr"),
                   numbered(out, "depth_", int(i), 4, ".png"));
      if ((i + 1) % 10 == 0 || i + 1 == path.size()) std::cout << "  frame " << i + 1 << "/" << path.size() << std::endl;
    }
    if (have_ffmpeg()) {
      const std::string mp4 = (fs::path(out) / "video.mp4").string();
      stylerf::host::write_atomic_with(mp4, [&](const std::string& tmp) {
        const std::string cmd = "ffmpeg -loglevel error -y -framerate 30 -i '" + out +
                                "/frame_%04d.png' -pix_fmt yuv420p -f mp4 '" + tmp + "'";
        if (std::system(cmd.c_str()) != 0) throw Error("ffmpeg failed: " + cmd);
      });
      std::cout << "video: " << mp4 << "\n";
    } else {
      std::cout << "ffmpeg not on PATH: frames only (ffmpeg -y -framerate 30 -i " << out
                << "/frame_%04d.png -pix_fmt yuv420p video.mp4)\n";
    }
  }
  std::cout << "rendered in " << std::fixed << std::setprecision(1)
            << std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() << " s -> " << out << "\n";
  return 0;
}

stylerf::cli::Register reg("render", "render a density-stage checkpoint: held-out views with PSNR/SSIM, or a camera path",
                           run_render);
}  // namespace
