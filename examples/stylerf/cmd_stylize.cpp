// stylerf stylize --ckpt STYLE_CKPT --style IMG [--style IMG ...] --views test|path [options] -o DIR:
// zero-shot stylisation with a trained style checkpoint: no optimisation, any style image.
//   - one --style (or several without --mix, or a folder): one output set per style (DIR, or DIR/<style>/
//     for several): frames (test_NNN.png | frame_NNNN.png), video.mp4 when ffmpeg is on PATH;
//   - --mix w1,w2,...: the styles' transforms interpolated into one set (DIR);
//   - --mix-grid A,B,C,D: the paper's 4-corner sheet of one view (DIR/mix_grid.png, 5 x 5 bilinear mix);
//   - --region SPEC --style-inside A --style-outside B: compositional transfer, plus the mask PNGs.
// --camera-path FILE: the path's outputs along the cameras of a nerfstudio camera_path.json (at its render
// size, or --size; the video at its fps unless --fps is given) instead of the built-in path.
// Per view, once for all styles: the content render (SICT, composited), depth/depth_NNNN.exr (depth along the
// ray in ray-space units, at the rendered map's resolution). DIR/metrics.json: the styles (cache keys),
// the time to encode the styles, to the first frame, frames/s after it, and per view and style the content
// and style losses (test views: also 2D AdaIN of the true view, by the same VGG and mask).
#include <boost/program_options.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <sstream>

#include "examples/stylerf/cli_checks.hpp"
#include "examples/stylerf/commands.hpp"
#include "examples/stylerf/help.hpp"
#include "examples/stylerf/frame_outputs.hpp"
#include "examples/stylerf/rank_outputs.hpp"
#include "examples/stylerf/refine_option.hpp"
#include "examples/stylerf/strength_option.hpp"
#include "examples/stylerf/stylize_losses.hpp"
#include "host/dist.hpp"
#include "host/error.hpp"
#include "host/files.hpp"
#include "lib/io/checkpoint.hpp"
#include "lib/io/exr.hpp"
#include "lib/io/image.hpp"
#include "lib/model/block_refine.hpp"
#include "lib/model/scene_style_stats.hpp"
#include "lib/model/style_model.hpp"
#include "lib/scene/camera_path.hpp"
#include "lib/scene/camera_path_json.hpp"
#include "lib/scene/scene_meta.hpp"
#include "lib/style/style_encoder.hpp"
#include "lib/style/style_image.hpp"

namespace po = boost::program_options;
namespace fs = std::filesystem;

namespace {

using stylerf::host::Error;
using Clock = std::chrono::steady_clock;
namespace model = stylerf::model;
namespace style = stylerf::style;
namespace cli = stylerf::cli;

using stylerf::cli::seconds_since;

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, sep)) out.push_back(item);
  return out;
}

std::vector<float> parse_weights(const std::string& s) {
  std::vector<float> w;
  for (const auto& item : split(s, ',')) {
    size_t used = 0;
    float x = 0;
    try {
      x = std::stof(item, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != item.size()) throw Error("--mix: '" + item + "' is not a number");
    w.push_back(x);
  }
  return w;
}

// A --style argument: an image, or a folder whose readable images are taken in name order (others are
// named and skipped).
std::vector<std::string> expand_styles(const std::vector<std::string>& args) {
  std::vector<std::string> out;
  for (const auto& a : args) {
    std::error_code ec;
    if (!fs::is_directory(a, ec)) {
      const std::string why = stylerf::io::image_unreadable_reason(a);
      if (!why.empty()) throw Error("--style " + a + ": " + why);
      out.push_back(a);
      continue;
    }
    std::vector<std::string> files = style::style_images_in(a, &std::cout);
    if (files.empty()) throw Error("--style " + a + ": the folder holds no readable image");
    out.insert(out.end(), files.begin(), files.end());
  }
  return out;
}

struct Job {  // one output set: a name, a folder, the code(s)
  std::string name, dir;
  style::StyleCode code, outside;  // outside: regions only
  std::string style_path;          // for the style loss (empty: mixed, regions)
};

void write_depth(const model::StyleModel::CameraContent& cc, const std::string& path) {
  const auto acc = cc.content.acc.to_host(), d = cc.content.depth.to_host();
  std::vector<float> depth(acc.size());
  for (size_t i = 0; i < acc.size(); ++i) depth[i] = acc[i] > 1e-6f ? d[i] / acc[i] : 0.0f;
  fs::create_directories(fs::path(path).parent_path());
  stylerf::io::write_exr(path, depth, cc.width, cc.height, 1);
}

// The 5 x 5 sheet: corners A (top left), B (top right), C (bottom left), D (bottom right), bilinear
// weights between them. Returns the smallest mean absolute difference between two corner cells (over the
// whole cell, RGB in [0, 1]): a stylizer that ignores its style input makes all 25 cells alike (a
// degenerate run measured 0.0008; a stylised object on a white background 0.017).
double mix_grid(const model::StyleModel& m, const model::SceneStyleStats& scene_stats,
                const model::StyleModel::CameraContent& cc, const std::vector<style::StyleCode>& c,
              int W, int H, bool over_bg, const std::string& png) {
  constexpr int kN = 5;
  stylerf::io::Image sheet;
  sheet.width = kN * W;
  sheet.height = kN * H;
  sheet.data.assign(size_t(3) * sheet.width * sheet.height, 1.0f);
  for (int gy = 0; gy < kN; ++gy)
    for (int gx = 0; gx < kN; ++gx) {
      const float u = gx / float(kN - 1), v = gy / float(kN - 1);
      style::StyleCode code =
          style::mix_codes(c, {(1 - u) * (1 - v), u * (1 - v), (1 - u) * v, u * v}, "--mix-grid");
      scene_stats.attach(code);
      auto rgb = m.stylize_camera(cc, code, W, H);
      if (over_bg) m.over_background(rgb, cc, W, H);
      for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x)
          for (int ch = 0; ch < 3; ++ch) sheet.at(ch, gy * H + y, gx * W + x) = rgb[(size_t(y) * W + x) * 3 + ch];
      std::cout << "  grid " << gy * kN + gx + 1 << "/" << kN * kN << "\r" << std::flush;
    }
  stylerf::io::save_png(png, sheet);
  const int corner[4][2] = {{0, 0}, {0, kN - 1}, {kN - 1, 0}, {kN - 1, kN - 1}};
  double closest = 1e9;
  for (int a = 0; a < 4; ++a)
    for (int b = a + 1; b < 4; ++b) {
      double sum = 0;
      for (int ch = 0; ch < 3; ++ch)
        for (int y = 0; y < H; ++y)
          for (int x = 0; x < W; ++x)
            sum += std::abs(sheet.at(ch, corner[a][0] * H + y, corner[a][1] * W + x) -
                            sheet.at(ch, corner[b][0] * H + y, corner[b][1] * W + x));
      closest = std::min(closest, sum / (3.0 * W * H));
    }
  std::cout << "\nsheet: " << png << " (closest corner cells differ by " << std::setprecision(4) << closest
            << " on average)\n";
  return closest;
}

// All of stylize's options, as parsed.
struct StylizeArgs {
  std::string ckpt, views = "path", out, scene_dir, device, mix, mix_grid, region, inside, outside, cache;
  std::vector<std::string> style_args;
  int frames = 120, max_views = 0, size = 0, chunk = 8192, fps = 30, supersample = 0;
  std::string supersample_text = "0";  // --supersample, parsed into supersample (0: the checkpoint's)
  float refine_contrast = model::kRefineContrast;
  float strength = stylerf::cli::kCheckpointStrength;  // --strength (the checkpoint's unless given)
  bool no_losses = false, decoded_background = false;
  std::string camera_path;                   // --camera-path FILE (empty: the built-in path)
  stylerf::scene::CameraPathFile path_file;  // its cameras, read before any loading
  bool fps_from_path = false;                // no --fps: the video plays at the file's fps
  bool test() const { return views == "test"; }
};

// Parses argv into a. Returns -1 to go on, else the exit code (the help was shown).
int parse_stylize_args(int argc, char** argv, StylizeArgs& a) {
  po::options_description desc("stylerf stylize --ckpt STYLE_CKPT --style IMG --views test|path -o DIR [options]");
  desc.add_options()("help,h", "show this help")("ckpt", po::value(&a.ckpt), "style checkpoint (train-style)")(
      "style", po::value(&a.style_args), "style image or folder of images (repeatable)")(
      "views", po::value(&a.views)->default_value("path"),
      "test (held-out views, with losses beside 2D AdaIN) or path")(
      "frames", po::value(&a.frames)->default_value(120), "frames of the camera path")(
      "camera-path", po::value(&a.camera_path)->value_name("FILE"),
      "stylise along the cameras of FILE, a nerfstudio camera_path.json, in the scene's world frame, instead of "
      "the built-in path (frames and video named as for it)")(
      "max-views", po::value(&a.max_views)->default_value(0), "render this many evenly spaced views (0: all)")(
      "size", po::value(&a.size)->default_value(0), "longer image side in pixels (0: the scene's)")(
      "mix", po::value(&a.mix), "weights w1,w2,... (one per --style, sum 1): interpolate the styles")(
      "mix-grid", po::value(&a.mix_grid), "A,B,C,D: the 5x5 four-corner interpolation sheet of the first view")(
      "region", po::value(&a.region), "box:x0,y0,z0,x1,y1,z1 | sphere:x,y,z,r | depth:d0,d1 (scene coordinates)")(
      "style-inside", po::value(&a.inside), "style inside --region")("style-outside", po::value(&a.outside),
                                                                       "style outside --region")(
      "output,o", po::value(&a.out), "output directory")(
      "scene", po::value(&a.scene_dir), "scene directory (default: the one the checkpoint was trained on)")(
      "cache", po::value(&a.cache), "style-code cache folder ('none': memory only; default: the user cache)")(
      "no-losses", po::bool_switch(&a.no_losses), "skip the per-view VGG losses")(
      "decoded-background", po::bool_switch(&a.decoded_background),
      "scenes with a background colour: keep the decoder's empty space instead of compositing over the colour")(
      "fps", po::value(&a.fps)->default_value(30), "video frame rate (with --camera-path: the file's unless given)")(
      "chunk", po::value(&a.chunk)->default_value(8192), "rays per renderer call (bounds memory)")(
      "supersample", stylerf::cli::supersample_value(&a.supersample_text), stylerf::cli::kSupersampleHelp)(
      "refine-contrast", stylerf::cli::refine_contrast_value(&a.refine_contrast), stylerf::cli::kRefineContrastHelp)(
      "strength", stylerf::cli::strength_value(&a.strength), stylerf::cli::kStrengthHelp)(
      "device", po::value(&a.device), stylerf::cli::kDeviceHelp);
  po::variables_map vm;
  po::store(po::parse_command_line(argc, argv, desc), vm);
  po::notify(vm);
  if (vm.count("help") || a.ckpt.empty()) {
    stylerf::cli::print_help(std::cout, "stylize", desc);
    return vm.count("help") ? 0 : 2;
  }
  if (!a.camera_path.empty()) {
    if (!vm["frames"].defaulted()) throw Error("--frames does not apply to --camera-path (the file gives the frames)");
    a.fps_from_path = vm["fps"].defaulted();
  }
  return -1;
}

// What the options ask to stylise with: the style images (checked readable), the four corners of a mix
// sheet, the mix weights; whether regions compose two styles.
struct StyleChoice {
  std::vector<std::string> styles, grid;
  std::vector<float> weights;
  bool regions = false;
};

// Every option checked before anything is loaded.
StyleChoice check_stylize_args(const StylizeArgs& a) {
  if (a.views != "test" && a.views != "path") throw Error("--views must be test or path (got '" + a.views + "')");
  if (a.frames < 1 || a.frames > 100000) throw Error("--frames must be in [1, 100000]");
  if (!a.camera_path.empty() && a.test())
    throw Error("--camera-path renders a path: it does not combine with --views test");
  if (a.max_views < 0) throw Error("--max-views must be >= 0");
  if (a.size < 0 || a.size > 8192) throw Error("--size must be in [0, 8192] (0: the scene's size)");
  if (a.chunk < 1) throw Error("--chunk must be >= 1");
  stylerf::cli::supersample_from(a.supersample_text);  // checked here, parsed after loading
  stylerf::cli::check_refine_contrast(a.refine_contrast);
  if (a.fps < 1 || a.fps > 240) throw Error("--fps must be in [1, 240]");
  if (a.out.empty()) throw Error("-o DIR is required");
  StyleChoice c;
  c.regions = !a.region.empty();
  if (c.regions && (a.inside.empty() || a.outside.empty()))
    throw Error("--region needs both --style-inside and --style-outside");
  if (!c.regions && (!a.inside.empty() || !a.outside.empty()))
    throw Error("--style-inside and --style-outside need --region");
  if (!a.mix_grid.empty() && (c.regions || !a.mix.empty()))
    throw Error("--mix-grid renders its own sheet: do not combine it with --mix or --region");
  if (!a.mix_grid.empty()) c.grid = split(a.mix_grid, ',');
  if (!a.mix_grid.empty() && c.grid.size() != 4) throw Error("--mix-grid takes four images A,B,C,D");
  if (c.regions) {
    if (!a.style_args.empty()) throw Error("with --region, give the styles as --style-inside and --style-outside");
    c.styles = expand_styles({a.inside, a.outside});
    if (c.styles.size() != 2) throw Error("--style-inside and --style-outside each take one image");
  } else if (!c.grid.empty()) {
    c.styles = expand_styles(c.grid);
  } else {
    if (a.style_args.empty()) throw Error("give a style image with --style (or --mix-grid, or --region)");
    c.styles = expand_styles(a.style_args);
  }
  if (!a.mix.empty()) {
    c.weights = parse_weights(a.mix);
    style::check_mix_weights(c.weights, c.styles.size(), "--mix");
  }
  return c;
}

// The views to render: the held-out cameras or the default path, `max_views` of them evenly picked, at
// the asked size. ids: their indices among the held-out views or the path's frames.
std::vector<stylerf::scene::Camera> pick_cameras(const StylizeArgs& a, const stylerf::scene::Scene& scene,
                                                 std::vector<int>& ids) {
  std::vector<stylerf::scene::Camera> cams;
  if (a.test()) {
    if (scene.test.empty()) throw Error("scene " + scene.root + " has no held-out views; use --views path");
    for (const auto& v : scene.test) cams.push_back(v.camera);
  } else {
    cams = a.camera_path.empty() ? stylerf::scene::default_path(scene, a.frames) : a.path_file.cameras;
  }
  const int n = int(cams.size()), k = a.max_views > 0 ? std::min(a.max_views, n) : n;
  std::vector<stylerf::scene::Camera> picked;
  for (int j = 0; j < k; ++j) {
    ids.push_back(int(int64_t(j) * n / k));
    picked.push_back(cams[size_t(ids.back())].with_longer_side(a.size));
  }
  return picked;
}

// Each style encoded (or read from the cache), with the scene's statistics attached; a row per style.
std::vector<style::StyleCode> encode_styles(style::StyleEncoder& enc, const model::SceneStyleStats& scene_stats,
                                            const std::vector<std::string>& styles, nlohmann::json& rows) {
  std::vector<style::StyleCode> codes;
  for (const auto& s : styles) {
    const auto t = Clock::now();
    const auto e = enc.encode(s);
    codes.push_back(e.code);
    scene_stats.attach(codes.back());
    rows.push_back({{"path", s}, {"key", e.key}, {"from_cache", e.from_cache}, {"encode_s", seconds_since(t)}});
    std::cout << "style " << s << (e.from_cache ? " (cached)" : "") << ": " << std::fixed << std::setprecision(3)
              << seconds_since(t) << " s\n";
  }
  return codes;
}

// One output set per style; or one of the mixed styles; or one of the two regions.
std::vector<Job> make_jobs(const StylizeArgs& a, const StyleChoice& c, const std::vector<style::StyleCode>& codes,
                           const model::SceneStyleStats& scene_stats) {
  std::vector<Job> jobs;
  if (c.regions) {
    jobs.push_back({"regions", a.out, codes[0], codes[1], ""});
  } else if (!c.weights.empty()) {
    jobs.push_back({"mix", a.out, style::mix_codes(codes, c.weights), {}, ""});
    scene_stats.attach(jobs.back().code);
  } else {
    for (size_t i = 0; i < c.styles.size(); ++i) {
      const std::string name = fs::path(c.styles[i]).stem().string();
      jobs.push_back({name, c.styles.size() == 1 ? a.out : (fs::path(a.out) / name).string(), codes[i], {},
                      c.styles[i]});
    }
  }
  for (const auto& j : jobs) fs::create_directories(j.dir);
  return jobs;
}

// Timings of the view loop, from the start of the work; the losses timed apart.
struct RenderTiming {
  double first_frame_s = -1, frame_time_after = 0, loss_s = 0, content_s = 0;
  int frames = 0;
  // Several ranks: frames of all ranks, and seconds from the start of the work until rank 0 had them all.
  int frames_all = 0;
  double all_s = 0;
  int64_t blocks = 0, refined = 0;  // feature-map blocks rendered, and those given n x n rays
  int merged_views = 0;             // views whose refined blocks were shaded per depth slab
  int slab_views = 0;               // views whose centre rays were shaded per depth slab
  double fps_after() const { return frames > 1 ? (frames - 1) / std::max(1e-9, frame_time_after) : 0.0; }
};

// What every view needs: the model, the scene, the region (or none), the losses (or none).
struct ViewWork {
  const model::StyleModel& m;
  const stylerf::scene::Scene& scene;
  const model::RegionHead* region;
  cli::ViewLosses* losses;
};

// Each view: its content rendered once (depth EXR, region mask), then each job's frame and losses.
nlohmann::json render_views(const StylizeArgs& a, const ViewWork& w, const std::vector<stylerf::scene::Camera>& cams,
                            const std::vector<int>& ids, const std::vector<Job>& jobs, Clock::time_point t_work,
                            RenderTiming& t) {
  const bool test = a.test();
  nlohmann::json per_view = nlohmann::json::array();
  for (size_t vi = 0; vi < cams.size(); ++vi) {
    if (!cli::my_view(vi)) continue;  // another rank's (mpirun)
    const auto& cam = cams[vi];
    const auto tc = Clock::now();
    const auto cc = w.m.render_camera_content(w.scene, cam, a.chunk, w.region, a.supersample, a.refine_contrast);
    t.blocks += int64_t(cc.width) * cc.height;
    t.refined += cc.refined;
    t.merged_views += cc.merged ? 1 : 0;
    t.slab_views += cc.slab_shaded ? 1 : 0;
    t.content_s += seconds_since(tc);
    const std::string stem = test ? "test_" : "frame_";
    const int digits = test ? 3 : 4, idx = test ? ids[vi] : int(vi);
    write_depth(cc, cli::numbered(fs::path(a.out) / "depth", "depth_", idx, digits, ".exr"));
    if (w.region)
      stylerf::io::save_png(cli::numbered(a.out, "mask_", idx, digits, ".png"),
                            cli::grey_image(cc.region_mask, cc.width, cc.height));
    nlohmann::json row = {{"view", idx}, {"styles", nlohmann::json::object()}};
    if (w.losses) {
      const auto tl = Clock::now();
      w.losses->begin_view(w.scene, test ? &w.scene.test[size_t(ids[vi])] : nullptr, cam, cc);
      t.loss_s += seconds_since(tl);
    }
    for (size_t ji = 0; ji < jobs.size(); ++ji) {
      const Job& j = jobs[ji];
      auto rgb = w.region ? w.m.stylize_camera_regions(cc, j.code, j.outside, cam.width, cam.height)
                          : w.m.stylize_camera(cc, j.code, cam.width, cam.height);
      if (!a.decoded_background) w.m.over_background(rgb, cc, cam.width, cam.height);
      stylerf::io::save_png(cli::numbered(j.dir, stem, idx, digits, ".png"),
                            cli::interleaved_image(rgb, cam.width, cam.height));
      ++t.frames;
      const double now = seconds_since(t_work) - t.loss_s;  // losses are timed apart
      if (t.first_frame_s < 0) t.first_frame_s = now;
      t.frame_time_after = now - t.first_frame_s;
      if (w.losses) {
        const auto tl = Clock::now();
        row["styles"][j.name] = w.losses->measure(rgb, cam.width, ji);
        t.loss_s += seconds_since(tl);
      }
    }
    per_view.push_back(row);
    std::cout << "  view " << vi + 1 << "/" << cams.size() << "  " << std::fixed << std::setprecision(2)
              << t.fps_after() << " frames/s" << std::endl;
  }
  return per_view;
}

// The videos (ffmpeg), metrics.json and the closing lines.
void finish_stylize(const StylizeArgs& a, const StyleChoice& c, const ViewWork& w, const std::vector<Job>& jobs,
                    const std::vector<stylerf::scene::Camera>& cams, const nlohmann::json& style_rows,
                    double encode_s, const RenderTiming& t, const nlohmann::json& per_view) {
  nlohmann::json vids = nlohmann::json::array();
  if (cams.size() > 1)
    for (const auto& j : jobs)
      if (cli::write_video(j.dir, a.test() ? "test_%03d.png" : "frame_%04d.png", "video.mp4", a.fps, std::cout))
        vids.push_back((fs::path(j.dir) / "video.mp4").string());
  nlohmann::json doc = {
      {"checkpoint", a.ckpt},
      {"scene", w.scene.root},
      {"views", a.views},
      {"size", {cams.front().width, cams.front().height}},
      {"styles", style_rows},
      {"outputs", nlohmann::json::array()},
      {"timing",
       {{"encode_styles_s", encode_s},
        {"first_frame_s", t.first_frame_s},
        {"frames", t.frames},
        {"frames_per_s_after_first", t.fps_after()},
        {"content_render_s_per_view", t.content_s / double(cams.size())},
        {"supersample", model::supersample_name(a.supersample)},
        {"refine_contrast", a.refine_contrast},
        {"strength", w.m.strength},
        {"refined_block_share", t.blocks > 0 ? double(t.refined) / double(t.blocks) : 0.0},
        {"merged_views", t.merged_views},
        {"slab_shaded_views", t.slab_views},
        {"losses_s", t.loss_s},
        {"note", "from the start of the work (weights, checkpoint and scene loaded); losses are timed apart and "
                 "excluded from frames/s"}}},
      {"videos", vids},
      {"per_view", per_view}};
  for (const auto& j : jobs) doc["outputs"].push_back({{"name", j.name}, {"dir", j.dir}});
  doc["ranks"] = {{"ranks", stylerf::host::Dist::world().size()},
                  {"frames", t.frames_all},
                  {"frames_per_s_after_encoding", t.frames_all / std::max(1e-9, t.all_s - encode_s)},
                  {"note", "all ranks' frames over the time from the styles encoded to the last frame at rank 0 "
                           "(views dealt round robin over the ranks; the timings above are rank 0's own)"}};
  if (c.regions) doc["region"] = a.region;
  if (!a.camera_path.empty()) doc["camera_path"] = a.camera_path;
  if (!c.weights.empty()) doc["mix"] = c.weights;
  if (w.losses) doc["mean_losses"] = w.losses->means();
  stylerf::host::write_file_atomic((fs::path(a.out) / "metrics.json").string(), doc.dump(2) + "\n");
  std::cout << std::fixed << std::setprecision(3) << "styles encoded in " << encode_s << " s; first frame at "
            << t.first_frame_s << " s; then " << t.fps_after() << " frames/s (" << t.frames << " frames)\n";
  std::cout << "content: ";
  if (a.supersample != 1)
    std::cout << (a.supersample == model::kQuincunx ? std::string("a quincunx of") : model::supersample_name(a.supersample))
              << " rays in "
              << (t.blocks > 0 ? 100.0 * double(t.refined) / double(t.blocks) : 0.0)
              << "% of the blocks (--refine-contrast " << a.refine_contrast << ")"
              << (t.merged_views > 0 ? ", shaded once per depth slab of a block (many samples a ray)" : "") << ", ";
  else
    std::cout << "one ray a block, ";
  if (t.slab_views > 0) std::cout << "centre rays shaded once per depth slab (many samples a ray), ";
  std::cout << t.content_s / double(cams.size()) << " s a view\n";
  if (w.losses) std::cout << w.losses->summary();
  std::cout << "-> " << a.out << "/metrics.json\n";
}

// The style checkpoint at a.ckpt (refused unless it holds a trained stylizer).
stylerf::io::Checkpoint load_style_checkpoint(const std::string& path) {
  auto ck = stylerf::io::load_checkpoint(path, "");
  if (ck.kind != "style")
    throw Error("checkpoint " + path + " holds a '" + ck.kind + "' stage, not a trained stylizer; train one with "
                "`stylerf train-style --features " + path + "`");
  return ck;
}

// The scene the checkpoint was trained on (or --scene), checked to be that scene.
stylerf::scene::Scene open_stylize_scene(const StylizeArgs& a, const stylerf::io::Checkpoint& ck) {
  stylerf::scene::SceneOverrides o;
  o.dir = a.scene_dir;
  o.load_images = a.test() && !a.no_losses;
  return stylerf::scene::open_scene_for(ck.meta.value("scene", nlohmann::json::object()), a.ckpt, o).scene;
}

int run_stylize(int argc, char** argv) {
  StylizeArgs a;
  if (const int code = parse_stylize_args(argc, argv, a); code >= 0) return code;
  const StyleChoice choice = check_stylize_args(a);
  if (!a.camera_path.empty()) {  // read before any loading, so that a bad file is refused at once
    a.path_file = stylerf::scene::read_camera_path_json(a.camera_path);
    if (a.fps_from_path) a.fps = std::clamp(int(std::lround(a.path_file.fps)), 1, 240);
  }

  // ---- loading (not counted in the timings) ----
  cli::init_runtime(a.device, false);
  const auto ck = load_style_checkpoint(a.ckpt);
  auto m = model::StyleModel::load(ck);
  stylerf::cli::apply_strength(m, a.strength);
  a.supersample = stylerf::cli::supersample_from(a.supersample_text);
  if (a.supersample == 0) a.supersample = m.inference_supersample;
  const auto scene = open_stylize_scene(a, ck);
  auto vgg = stylerf::nn::VggEncoder::load_default();
  std::unique_ptr<cli::ViewLosses> losses;
  if (!a.no_losses) losses = std::make_unique<cli::ViewLosses>(m, vgg, a.test());
  std::vector<int> ids;
  const std::vector<stylerf::scene::Camera> cams = pick_cameras(a, scene, ids);
  std::unique_ptr<model::RegionHead> region;
  if (choice.regions)
    region = std::make_unique<model::RegionHead>(model::Region::parse(a.region, cams),
                                                 model::RegionSpace::of(m.features.geo, scene));
  fs::create_directories(a.out);

  // ---- the work: encode the styles, then each view ----
  const auto t_work = Clock::now();
  style::StyleEncoder enc(m.dst, vgg,
                          a.cache == "none" ? "" : a.cache.empty() ? style::StyleEncoder::default_cache_dir() : a.cache);
  nlohmann::json style_rows = nlohmann::json::array();
  // The vgg-adain-relu4 decoder's, once per scene, at the frames' rays a block.
  const model::SceneStyleStats scene_stats(m, scene, model::SceneStyleStats::kDefaultViews, a.supersample,
                                           a.refine_contrast);
  const std::vector<style::StyleCode> codes = encode_styles(enc, scene_stats, choice.styles, style_rows);
  const double encode_s = seconds_since(t_work);
  if (!choice.grid.empty()) {
    if (!stylerf::host::Dist::world().root()) return 0;  // one sheet: rank 0 alone
    const auto& cam = cams.front();
    const auto cc = m.render_camera_content(scene, cam, a.chunk, nullptr, a.supersample, a.refine_contrast);
    const double closest = mix_grid(m, scene_stats, cc, codes, cam.width, cam.height, !a.decoded_background,
                                    (fs::path(a.out) / "mix_grid.png").string());
    stylerf::host::write_file_atomic((fs::path(a.out) / "metrics.json").string(),
                                     nlohmann::json{{"styles", style_rows},
                                                    {"encode_s", encode_s},
                                                    {"sheet_s", seconds_since(t_work)},
                                                    {"corner_min_mean_abs_diff", closest}}.dump(2) +
                                         "\n");
    return 0;
  }
  // Under mpirun every rank renders its share of the views into a folder of its own; rank 0 collects them.
  StylizeArgs mine = a;
  mine.out = cli::rank_output_dir(a.out);
  const std::vector<Job> jobs = make_jobs(mine, choice, codes, scene_stats);
  if (losses)
    for (const auto& j : jobs) losses->add_style(j.style_path);
  const ViewWork work{m, scene, region.get(), losses.get()};
  RenderTiming timing;
  nlohmann::json per_view = render_views(mine, work, cams, ids, jobs, t_work, timing);
  auto& dist = stylerf::host::Dist::world();
  timing.frames_all = timing.frames;
  if (dist.size() > 1) {
    cli::collect_rank_outputs(mine.out, a.out);
    per_view = cli::gather_view_rows(per_view);
    if (losses) losses->merge_ranks();
    std::vector<double> frames = {double(timing.frames)};
    dist.allreduce_sum(frames);
    timing.frames_all = int(frames[0]);
  }
  timing.all_s = seconds_since(t_work);
  if (!dist.root()) return 0;  // rank 0 writes the videos and metrics.json
  finish_stylize(a, choice, work, jobs, cams, style_rows, encode_s, timing, per_view);
  return 0;
}

cli::Register reg("stylize", run_stylize);
}  // namespace
