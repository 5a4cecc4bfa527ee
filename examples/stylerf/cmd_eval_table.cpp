// stylerf eval table --scene-ckpts DENSITY[,STYLE...] [...] [--styles IMG|DIR ...] -o DIR: StyleRF's Table 1.
//
// Per scene (one --scene-ckpts group: a density checkpoint, then any style checkpoints of the same scene,
// e.g. StyleRF and its ablations), the path's warps are found once from the density geometry, then scored:
//   RGB (the unstylised floor), per-frame 2D AdaIN of the RGB frames, and each style checkpoint, for every
//   style (default: the held-out styles of the first style checkpoint given, for every scene; --max-styles
//   evenly spaced).
// Writes DIR/table.md (methods x short/long x LPIPS/RMSE, per scene and over all, with StyleRF/AdaIN
// ratios), DIR/table.json (every pair), and per scene DIR/<scene>/side_by_side.mp4 (AdaIN | StyleRF, first
// style) and DIR/<scene>/per_frame_rmse.svg (short-range RMSE per frame pair, mean over styles; axes,
// units and a legend).
#include <boost/program_options.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <map>
#include <sstream>

#include "examples/stylerf/commands.hpp"
#include "examples/stylerf/eval_setup.hpp"
#include "examples/stylerf/help.hpp"
#include "examples/stylerf/frame_outputs.hpp"
#include "examples/stylerf/rank_outputs.hpp"
#include "examples/stylerf/refine_option.hpp"
#include "examples/stylerf/strength_option.hpp"
#include "host/dist.hpp"
#include "host/error.hpp"
#include "host/files.hpp"
#include "lib/eval/path_frames.hpp"
#include "lib/eval/plot.hpp"
#include "lib/model/density_model.hpp"
#include "lib/model/scene_style_stats.hpp"
#include "lib/model/style_model.hpp"
#include "lib/style/style_encoder.hpp"
#include "lib/style/style_image.hpp"

namespace po = boost::program_options;
namespace fs = std::filesystem;

namespace stylerf::cli {

namespace {

using host::Error;
using Clock = std::chrono::steady_clock;

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, sep))
    if (!item.empty()) out.push_back(item);
  return out;
}

// A method's scores on one scene: one ConsistencyScore per style (RGB: one, style-independent).
struct MethodRows {
  std::string name;
  std::vector<std::string> styles;
  std::vector<eval::ConsistencyScore> scores;

  double mean(bool long_range, bool lpips) const {
    double s = 0;
    int n = 0;
    for (const auto& sc : scores) {
      const auto& r = long_range ? sc.long_range : sc.short_range;
      const double v = lpips ? r.lpips : r.rmse;
      if (std::isfinite(v)) s += v, ++n;
    }
    return n ? s / n : std::nan("");
  }
  // Short-range RMSE per frame pair, mean over styles.
  std::vector<double> per_pair_rmse() const {
    std::vector<double> out;
    if (scores.empty()) return out;
    out.assign(scores.front().short_range.pairs.size(), 0.0);
    for (size_t i = 0; i < out.size(); ++i) {
      int n = 0;
      for (const auto& sc : scores)
        if (std::isfinite(sc.short_range.pairs[i].rmse)) out[i] += sc.short_range.pairs[i].rmse, ++n;
      out[i] = n ? out[i] / n : std::nan("");
    }
    return out;
  }
};

// "StyleRF (<file stem>[, recipe][, ablations])": rows of several checkpoints must be told apart.
std::string style_model_label(const io::Checkpoint& ck) {
  const auto sm = ck.meta.value("style_model", nlohmann::json::object());
  const std::string sict = sm.value("sict", "volume-adaptive");
  std::string label = "StyleRF (" + fs::path(ck.path).stem().string();
  label += std::string(", ") + sm.value("decoder", "stage2") + " decoder";
  if (sict != "volume-adaptive") label += ", sict " + sict;
  if (!sm.value("dst_bias", true)) label += ", dst no-bias";
  if (sm.value("content_skip", false)) label += ", content skip";
  return label + ")";
}

std::vector<std::string> pick_evenly(const std::vector<std::string>& all, int n) {
  if (n <= 0 || int(all.size()) <= n) return all;
  std::vector<std::string> out;
  for (int i = 0; i < n; ++i) out.push_back(all[size_t(int64_t(i) * int64_t(all.size()) / n)]);
  return out;
}

std::string fmt(double v, int digits = 4) {
  if (!std::isfinite(v)) return "–";
  std::ostringstream o;
  o << std::fixed << std::setprecision(digits) << v;
  return o.str();
}

io::Image side_by_side(const io::Image& a, const io::Image& b) {
  io::Image out;
  out.width = a.width + b.width;
  out.height = std::max(a.height, b.height);
  out.data.assign(size_t(3) * out.width * out.height, 1.0f);
  for (int c = 0; c < 3; ++c) {
    for (int y = 0; y < a.height; ++y)
      for (int x = 0; x < a.width; ++x) out.at(c, y, x) = a.at(c, y, x);
    for (int y = 0; y < b.height; ++y)
      for (int x = 0; x < b.width; ++x) out.at(c, y, a.width + x) = b.at(c, y, x);
  }
  return out;
}

struct SceneResult {
  std::string name;
  std::vector<MethodRows> methods;
  nlohmann::json json;
};

void markdown_rows(std::ostream& md, const std::vector<MethodRows>& methods) {
  md << "| method | short LPIPS | short RMSE | long LPIPS | long RMSE |\n|---|---|---|---|---|\n";
  for (const auto& m : methods)
    md << "| " << m.name << " | " << fmt(m.mean(false, true)) << " | " << fmt(m.mean(false, false)) << " | "
       << fmt(m.mean(true, true)) << " | " << fmt(m.mean(true, false)) << " |\n";
  const MethodRows* adain = nullptr;
  for (const auto& m : methods)
    if (m.name == "AdaIN (per frame)") adain = &m;
  if (!adain) return;
  for (const auto& m : methods) {
    if (m.name.rfind("StyleRF", 0) != 0) continue;
    md << "\n" << m.name << " / AdaIN: short RMSE " << fmt(m.mean(false, false) / adain->mean(false, false), 3)
       << "x, long RMSE " << fmt(m.mean(true, false) / adain->mean(true, false), 3) << "x, short LPIPS "
       << fmt(m.mean(false, true) / adain->mean(false, true), 3) << "x, long LPIPS "
       << fmt(m.mean(true, true) / adain->mean(true, true), 3)
       << "x (paper, Table 1: RMSE 0.67x short, 0.74x long; LPIPS 0.47x short, 0.68x long)\n";
  }
}

}  // namespace

// All of eval table's options, as parsed.
struct TableArgs {
  std::vector<std::string> groups, style_args;
  std::string out, device, lpips_net = eval::lpips_net_name(eval::kDefaultLpipsNet);
  PathOptions p;
  int max_styles = 5, fps = 8;
  bool no_lpips = false;
};

// Parses argv into a. Returns -1 to go on, else the exit code (the help was shown).
int parse_table_args(int argc, char** argv, TableArgs& a) {
  po::options_description desc("stylerf eval table --scene-ckpts DENSITY[,STYLE...] [...] -o DIR [options]");
  desc.add_options()("help,h", "show this help")(
      "scene-ckpts", po::value(&a.groups)->multitoken(),
      "per scene: a density checkpoint, then style checkpoints of that scene (comma-separated)")(
      "styles", po::value(&a.style_args)->multitoken(),
      "style images or folders (default: the first style checkpoint's held-out styles)")(
      "max-styles", po::value(&a.max_styles)->default_value(5), "styles per scene, evenly spaced (0: all)")(
      "scored-frames", po::value(&a.p.frames)->default_value(16), "frames compared: the first N of the path")(
      "path-frames", po::value(&a.p.path_frames)->default_value(120), "frames of the whole path (their spacing)")(
      "size", po::value(&a.p.size)->default_value(0), "longer image side (0: the scene's)")(
      "depth-tol", stylerf::cli::value_shown(&a.p.depth_tolerance), "occlusion test: relative depth tolerance")(
      "no-lpips", po::bool_switch(&a.no_lpips), "RMSE only")(
      "lpips-net", po::value(&a.lpips_net)->default_value(a.lpips_net), "LPIPS trunk: vgg | alex")(
      "fps", po::value(&a.fps)->default_value(8), "side-by-side video frame rate")(
      "output,o", po::value(&a.out), "output directory")(
      "chunk", po::value(&a.p.chunk)->default_value(8192), "rays per renderer call")(
      "supersample", stylerf::cli::supersample_value(&a.p.supersample_text), stylerf::cli::kSupersampleHelp)(
      "refine-contrast", stylerf::cli::refine_contrast_value(&a.p.refine_contrast), stylerf::cli::kRefineContrastHelp)(
      "strength", stylerf::cli::strength_value(&a.p.strength), stylerf::cli::kStrengthHelp)(
      "device", po::value(&a.device), stylerf::cli::kDeviceHelp);
  stylerf::cli::apply_renamed_flags("eval table", argc, argv, {{"--frames", "--scored-frames"}});
  po::variables_map vm;
  po::store(po::parse_command_line(argc, argv, desc), vm);
  po::notify(vm);
  if (vm.count("help") || a.groups.empty()) {
    stylerf::cli::print_help(std::cout, "eval table", desc);
    return vm.count("help") ? 0 : 2;
  }
  return -1;
}

// The checkpoints of each scene group and the styles to score, checked before the work: the groups'
// files, the style images, the style checkpoints (loaded once; a wrong kind is refused early).
struct TableInputs {
  std::vector<std::vector<std::string>> scene_ckpts;
  std::vector<std::vector<io::Checkpoint>> style_cks;
  std::vector<std::string> explicit_styles, default_styles;
  const std::vector<std::string>& styles() const { return explicit_styles.empty() ? default_styles : explicit_styles; }
};

TableInputs check_table_args(TableArgs& a) {  // parses --supersample into a.p
  check_path_options(a.p);
  if (a.out.empty()) throw Error("-o DIR is required");
  if (a.max_styles < 0) throw Error("--max-styles must be >= 0");
  if (a.fps < 1 || a.fps > 240) throw Error("--fps must be in [1, 240]");
  TableInputs in;
  for (const auto& g : a.groups) {
    in.scene_ckpts.push_back(split(g, ','));
    if (in.scene_ckpts.back().empty()) throw Error("--scene-ckpts: an empty group");
    for (const auto& f : in.scene_ckpts.back())
      if (!fs::is_regular_file(f)) throw Error("--scene-ckpts: " + f + " is not a file");
  }
  for (const auto& s : a.style_args) {
    if (fs::is_directory(s)) {
      const auto files = style::style_images_in(s, &std::cout);
      in.explicit_styles.insert(in.explicit_styles.end(), files.begin(), files.end());
    } else {
      const std::string why = io::image_unreadable_reason(s);
      if (!why.empty()) throw Error("--styles " + s + ": " + why);
      in.explicit_styles.push_back(s);
    }
  }
  if (!a.style_args.empty() && in.explicit_styles.empty()) throw Error("--styles: no readable image");
  in.style_cks.resize(in.scene_ckpts.size());
  for (size_t gi = 0; gi < in.scene_ckpts.size(); ++gi)
    for (size_t i = 1; i < in.scene_ckpts[gi].size(); ++i) {
      in.style_cks[gi].push_back(io::load_checkpoint(in.scene_ckpts[gi][i], ""));
      if (in.style_cks[gi].back().kind != "style")
        throw Error("--scene-ckpts: " + in.scene_ckpts[gi][i] + " holds a '" + in.style_cks[gi].back().kind +
                    "' stage, not a style stage");
    }
  // Without --styles: the held-out styles (never trained on) of the first style checkpoint given, for
  // every scene, so scenes without a style stage are scored on the same styles.
  for (const auto& group : in.style_cks)
    for (const auto& ck : group)
      if (in.explicit_styles.empty() && in.default_styles.empty()) {
        in.default_styles = ck.meta.value("styles", nlohmann::json::object())
                                .value("holdout", nlohmann::json::array())
                                .get<std::vector<std::string>>();
        if (in.default_styles.empty()) throw Error(ck.path + " holds no held-out styles; give --styles");
      }
  return in;
}

// What scoring one scene's styles needs: the frames compared and how to score them.
struct SceneWork {
  const scene::Scene& scene;
  const PathSetup& path;
  const std::vector<io::Image>& rgb;
  const eval::MaskedDistance* dist;
  const PathOptions& p;
};

// Per style: per-frame AdaIN of the RGB frames, then each style checkpoint's frames, each scored. Rows:
// AdaIN, then one per checkpoint; first_*: the first style's frames (the side-by-side video).
std::vector<MethodRows> score_styles(const SceneWork& w, const std::vector<io::Checkpoint>& cks,
                                     const std::vector<std::string>& styles, style::AdainModel& adain,
                                     std::vector<io::Image>& first_adain, std::vector<io::Image>& first_stylerf) {
  MethodRows adain_rows{"AdaIN (per frame)", {}, {}};
  std::vector<std::unique_ptr<model::StyleModel>> models;
  std::vector<std::unique_ptr<style::StyleEncoder>> encoders;  // one per model: its codes are its own
  std::vector<model::SceneStyleStats> scene_stats;              // one per model: its views rendered once
  std::vector<MethodRows> rows;
  for (const auto& ck : cks) {
    models.push_back(std::make_unique<model::StyleModel>(model::StyleModel::load(ck)));
    apply_strength(*models.back(), w.p.strength);
    scene_stats.emplace_back(*models.back(), w.scene, model::SceneStyleStats::kDefaultViews, w.p.supersample,
                             w.p.refine_contrast);  // 0: the model's own rays a block, as its frames
    encoders.push_back(std::make_unique<style::StyleEncoder>(models.back()->dst, adain.encoder,
                                                             style::StyleEncoder::default_cache_dir()));
    rows.push_back({style_model_label(ck), {}, {}});
  }
  // Each model's content of the path's frames, once for every style (the style-independent bulk of a frame).
  std::vector<std::vector<model::StyleModel::CameraContent>> contents;
  for (const auto& m : models) {
    const auto t = Clock::now();
    contents.push_back(eval::content_frames(*m, w.scene, w.path.cams, w.p.chunk,
                                            w.p.supersample != 0 ? w.p.supersample : m->inference_supersample,
                                            w.p.refine_contrast));
    std::cout << "  content of " << w.path.cams.size() << " frames rendered once for all styles ("
              << fmt(seconds_since(t), 1) << " s)" << std::endl;
  }
  // Styles are dealt round robin over MPI ranks (one process: all of them); rank 0 has the first style, whose
  // frames make the side-by-side video.
  nlohmann::json mine = nlohmann::json::array();
  for (size_t si = 0; si < styles.size(); ++si) {
    if (!my_view(si)) continue;
    const std::string& st = styles[si];
    const auto t = Clock::now();
    const auto a = eval::adain_frames(adain, w.rgb, eval::load_style_for_eval(st));
    adain_rows.styles.push_back(st);
    adain_rows.scores.push_back(eval::score_frames(a, w.path.warps, w.dist));
    std::cout << "  [" << si + 1 << "/" << styles.size() << "] " << fs::path(st).stem().string() << "\n    AdaIN: "
              << score_line(adain_rows.scores.back()) << "\n";
    if (si == 0) first_adain = a;
    for (size_t mi = 0; mi < models.size(); ++mi) {
      style::StyleCode code = encoders[mi]->encode(st).code;
      scene_stats[mi].attach(code);
      const auto f = eval::stylerf_frames(*models[mi], contents[mi], w.path.cams, code,
                                          models[mi]->features.geo.has_background);
      rows[mi].styles.push_back(st);
      rows[mi].scores.push_back(eval::score_frames(f, w.path.warps, w.dist));
      std::cout << "    " << rows[mi].name << ": " << score_line(rows[mi].scores.back()) << "\n";
      if (si == 0 && mi == 0) first_stylerf = f;
    }
    std::cout << "    (" << fmt(seconds_since(t), 1) << " s)" << std::endl;
    nlohmann::json row = {{"view", si}, {"adain", adain_rows.scores.back().to_json()}, {"models", nlohmann::json::array()}};
    for (const auto& r : rows) row["models"].push_back(r.scores.back().to_json());
    mine.push_back(row);
  }
  if (host::Dist::world().size() > 1) {  // every rank's styles on rank 0, in the list's order
    adain_rows.styles.clear(), adain_rows.scores.clear();
    for (auto& r : rows) r.styles.clear(), r.scores.clear();
    for (const auto& row : gather_view_rows(mine)) {
      const std::string& st = styles[row.at("view").get<size_t>()];
      adain_rows.styles.push_back(st);
      adain_rows.scores.push_back(eval::ConsistencyScore::from_json(row.at("adain")));
      for (size_t mi = 0; mi < rows.size(); ++mi) {
        rows[mi].styles.push_back(st);
        rows[mi].scores.push_back(eval::ConsistencyScore::from_json(row.at("models").at(mi)));
      }
    }
  }
  rows.insert(rows.begin(), adain_rows);
  return rows;
}

// The scene's folder: the side-by-side video of the first style (AdaIN | StyleRF) and the per-frame
// short-range RMSE plot.
void write_scene_outputs(const fs::path& sdir, const SceneResult& res, const std::vector<io::Image>& first_adain,
                         const std::vector<io::Image>& first_stylerf, int fps) {
  if (!first_stylerf.empty()) {
    const fs::path vdir = sdir / "side_by_side";
    fs::create_directories(vdir);
    for (size_t i = 0; i < first_adain.size(); ++i)
      io::save_png(numbered(vdir, "frame_", int(i), 4, ".png"), side_by_side(first_adain[i], first_stylerf[i]));
    write_video(vdir.string(), "frame_%04d.png", "side_by_side.mp4", fps, std::cout);
  }
  std::vector<eval::PlotSeries> series;
  for (size_t i = 0; i < res.methods.size(); ++i)
    series.push_back({res.methods[i].name, eval::plot_colour(int(i)), res.methods[i].per_pair_rmse()});
  eval::PlotLabels labels;
  labels.title = res.name + ": short-range consistency per frame pair (lower is steadier)";
  labels.x_label = "frame pair (t - 1, t) along the path";
  labels.y_label = "RMSE of the warped frame (RGB in [0, 1])";
  labels.x_first = 1;
  host::write_file_atomic((sdir / "per_frame_rmse.svg").string(), eval::line_plot_svg(series, labels));
}

nlohmann::json methods_json(const std::vector<MethodRows>& methods) {
  nlohmann::json mj = nlohmann::json::array();
  for (const auto& m : methods) {
    nlohmann::json per = nlohmann::json::array();
    for (size_t i = 0; i < m.scores.size(); ++i) per.push_back({{"style", m.styles[i]}, {"score", m.scores[i].to_json()}});
    mj.push_back({{"method", m.name},
                  {"short", {{"lpips", m.mean(false, true)}, {"rmse", m.mean(false, false)}}},
                  {"long", {{"lpips", m.mean(true, true)}, {"rmse", m.mean(true, false)}}},
                  {"per_style", per}});
  }
  return mj;
}

// One scene group: its density checkpoint's geometry and RGB frames, then every style scored.
SceneResult eval_scene(const TableArgs& a, const TableInputs& in, size_t gi, style::AdainModel& adain,
                       const eval::MaskedDistance* dist, std::vector<std::string>& used_folders) {
  const auto& group = in.scene_ckpts[gi];
  const auto ck_d = io::load_checkpoint(group.front(), "");
  if (ck_d.kind != "density")
    throw Error("--scene-ckpts: the first checkpoint of a group must be a density checkpoint; " + group.front() +
                " holds a '" + ck_d.kind + "' stage");
  if (in.styles().empty())
    throw Error("--styles is needed: no style checkpoint was given to take held-out styles from");
  const auto scene = scene_of_checkpoint(ck_d);
  const auto density = model::load_model(ck_d);
  for (const auto& ck : in.style_cks[gi]) check_same_scene_of(ck_d, ck, scene);
  const std::vector<std::string> styles = pick_evenly(in.styles(), a.max_styles);

  SceneResult res;
  res.name = scene.name;
  // Groups of the same scene (e.g. two recipes' density checkpoints) get folders of their own.
  std::string folder = scene.name;
  for (int k = 2; std::count(used_folders.begin(), used_folders.end(), folder); ++k)
    folder = scene.name + "_" + std::to_string(k);
  used_folders.push_back(folder);
  const fs::path sdir = fs::path(a.out) / folder;
  if (host::Dist::world().root()) fs::create_directories(sdir);
  std::cout << "== " << scene.name << " (" << group.front() << "): " << styles.size() << " styles\n";
  // The RGB floor's frames and the geometry every method is warped by, from one render of the density.
  const auto t_rgb = Clock::now();
  std::vector<eval::FrameGeometry> geometry;
  const auto rgb = eval::rgb_frames(density, scene, eval::path_cameras(scene, a.p.frames, a.p.path_frames, a.p.size),
                                    a.p.chunk, &geometry);
  const double rgb_s = seconds_since(t_rgb);
  const PathSetup path = path_setup(std::move(geometry), density.geo, scene, a.p);
  std::cout << "  RGB and geometry: " << path.cams.size() << " frames of " << path.cams.front().width << "x"
            << path.cams.front().height << " rendered in " << fmt(rgb_s, 1) << " s, warps in " << fmt(path.seconds, 1)
            << " s" << std::endl;
  MethodRows rgb_rows{"RGB (unstylised floor)", {""}, {eval::score_frames(rgb, path.warps, dist)}};
  std::cout << "  RGB: " << score_line(rgb_rows.scores.back()) << "\n";
  std::vector<io::Image> first_adain, first_stylerf;
  res.methods.push_back(rgb_rows);
  for (auto& m : score_styles({scene, path, rgb, dist, a.p}, in.style_cks[gi], styles, adain, first_adain,
                              first_stylerf))
    res.methods.push_back(m);
  if (host::Dist::world().root()) write_scene_outputs(sdir, res, first_adain, first_stylerf, a.fps);
  res.json = {{"scene", scene.name},
              {"checkpoints", group},
              {"frames", {path.cams.front().width, path.cams.front().height}},
              {"methods", methods_json(res.methods)}};
  return res;
}

// Over all scenes: methods by name (in first-seen order), every style's score of every scene.
std::vector<MethodRows> all_scenes_rows(const std::vector<SceneResult>& results) {
  std::map<std::string, std::vector<const MethodRows*>> by_name;
  std::vector<std::string> order;
  for (const auto& r : results)
    for (const auto& m : r.methods) {
      if (!by_name.count(m.name)) order.push_back(m.name);
      by_name[m.name].push_back(&m);
    }
  std::vector<MethodRows> all;
  for (const auto& name : order) {
    MethodRows m{name, {}, {}};
    for (const auto* part : by_name[name])
      for (size_t i = 0; i < part->scores.size(); ++i) m.scores.push_back(part->scores[i]), m.styles.push_back(part->styles[i]);
    all.push_back(m);
  }
  return all;
}

// table.md: the protocol, then a table per scene (and over all scenes).
std::string table_markdown(const TableArgs& a, const std::vector<SceneResult>& results, bool lpips, double total) {
  const PathOptions& p = a.p;
  std::ostringstream md;
  md << "# Consistency (StyleRF Table 1 protocol, by the scenes' own geometry)\n\n"
     << "First " << p.frames << " frames of each scene's default path of " << p.path_frames
     << " frames; frame t warped into t-1 (short) and t-7 (long) by frame t's rendered depth; occlusion tolerance "
     << p.depth_tolerance << " (relative); background and off-image pixels masked. RMSE of RGB in [0,1]; LPIPS "
     << (lpips ? a.lpips_net + " v0.1, masked (each layer's map averaged over valid pixels)" : std::string("not measured"))
     << ". StyleRF content: "
     << (p.supersample == 0 ? std::string("each checkpoint's recipe's rays per feature-map block (n x n averaged, or "
                                          "a quincunx: the centre and the four shared corner rays)")
         : p.supersample == model::kQuincunx
             ? std::string("a quincunx of rays per feature-map block (the centre, weight 4, and the four corner rays "
                           "shared with the neighbouring blocks)")
             : model::supersample_name(p.supersample) +
                   (p.supersample > 1 ? " rays per feature-map block, averaged" : " ray per feature-map block (its centre)"))
     << (p.supersample == 1 ? std::string()
         : p.refine_contrast > 0 ? ", in the blocks whose centre differs from a neighbour's by more than " +
                                       fmt(p.refine_contrast, 2) + " (the centre ray elsewhere)"
                                 : std::string(", in every block"))
     << ". Means over styles and frame pairs. Plot colours: ";
  for (size_t i = 0; i < (results.empty() ? 0 : results.front().methods.size()); ++i)
    md << (i ? ", " : "") << results.front().methods[i].name << " " << eval::plot_colour_name(int(i));
  md << ".\n";
  for (const auto& r : results) {
    md << "\n## " << r.name << "\n\n";
    markdown_rows(md, r.methods);
  }
  if (results.size() > 1) {
    md << "\n## All scenes\n\n";
    markdown_rows(md, all_scenes_rows(results));
  }
  md << "\n(" << fmt(total, 0) << " s in all)\n";
  return md.str();
}

int run_eval_table(int argc, char** argv) {
  TableArgs a;
  if (const int code = parse_table_args(argc, argv, a); code >= 0) return code;
  const eval::LpipsNet net = eval::parse_lpips_net(a.lpips_net);
  const TableInputs in = check_table_args(a);

  init_runtime(a.device, false);
  auto adain = style::AdainModel::load_default();
  std::unique_ptr<eval::Lpips> lpips;
  if (!a.no_lpips) lpips = std::make_unique<eval::Lpips>(eval::Lpips::load_default(net));
  const auto dist = lpips_distance(lpips.get());
  if (host::Dist::world().root()) fs::create_directories(a.out);
  const auto t_all = Clock::now();
  std::vector<SceneResult> results;
  std::vector<std::string> used_folders;
  for (size_t gi = 0; gi < in.scene_ckpts.size(); ++gi)
    results.push_back(eval_scene(a, in, gi, adain, dist.get(), used_folders));

  const double total = seconds_since(t_all);
  const std::string md = table_markdown(a, results, lpips != nullptr, total);
  nlohmann::json doc = {{"frames", a.p.frames},
                        {"path_frames", a.p.path_frames},
                        {"depth_tolerance", a.p.depth_tolerance},
                        {"supersample", a.p.supersample == 0 ? std::string("each checkpoint's") : model::supersample_name(a.p.supersample)},
                        {"refine_contrast", a.p.refine_contrast},
                        {"strength", a.p.strength < 0 ? nlohmann::json("each checkpoint's") : nlohmann::json(a.p.strength)},
                        {"lpips", lpips ? a.lpips_net : std::string("none")},
                        {"seconds", total},
                        {"scenes", nlohmann::json::array()}};
  for (const auto& r : results) doc["scenes"].push_back(r.json);
  if (!host::Dist::world().root()) return 0;  // rank 0 writes the table
  host::write_file_atomic((fs::path(a.out) / "table.md").string(), md);
  host::write_file_atomic((fs::path(a.out) / "table.json").string(), doc.dump(2) + "\n");
  std::cout << "\n" << md << "-> " << a.out << "/table.md, table.json\n";
  return 0;
}

}  // namespace stylerf::cli
