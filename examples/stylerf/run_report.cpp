#include "examples/stylerf/run_report.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <sstream>

#include "host/error.hpp"
#include "host/files.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace stylerf::cli {
namespace {

json read_json(const fs::path& p) {
  std::ifstream f(p);
  if (!f) throw host::Error("stylerf run: " + p.string() + " is missing (its step did not write it)");
  try {
    return json::parse(f);
  } catch (const std::exception& e) {
    throw host::Error("stylerf run: " + p.string() + " is not valid JSON: " + e.what());
  }
}

double number(const json& j, const char* key) {
  return j.contains(key) && j.at(key).is_number() ? j.at(key).get<double>() : std::nan("");
}

std::string fmt(double v, int digits) {
  if (!std::isfinite(v)) return "–";
  std::ostringstream o;
  o << std::fixed << std::setprecision(digits) << v;
  return o.str();
}

std::string html_escape(const std::string& s) {
  std::string o;
  for (char c : s) o += c == '<' ? "&lt;" : c == '>' ? "&gt;" : c == '&' ? "&amp;" : c == '"' ? "&quot;" : std::string(1, c);
  return o;
}

// A path the page can link to: relative to OUT.
std::string link(const fs::path& out, const std::string& p) {
  return fs::absolute(p).lexically_relative(fs::absolute(out)).generic_string();
}

std::string stem(const std::string& p) { return fs::path(p).stem().string(); }

// The consistency ratios of the first StyleRF row over per-frame AdaIN's, from eval table's table.json.
json consistency_ratios(const json& table) {
  json r = json::object();
  if (!table.contains("scenes") || table["scenes"].empty()) return r;
  const json* adain = nullptr;
  const json* ours = nullptr;
  for (const auto& m : table["scenes"][0]["methods"]) {
    const std::string name = m.value("method", "");
    if (name == "AdaIN (per frame)") adain = &m;
    if (!ours && name.rfind("StyleRF", 0) == 0) ours = &m;
  }
  if (!adain || !ours) return r;
  for (const char* range : {"short", "long"})
    for (const char* metric : {"rmse", "lpips"})
      r[std::string(range) + "_" + metric + "_ratio"] =
          number((*ours)[range], metric) / number((*adain)[range], metric);
  r["lpips_net"] = table.value("lpips", std::string("none"));  // the LPIPS trunk (eval table --lpips-net)
  r["stylerf_short_rmse"] = number((*ours)["short"], "rmse");
  r["adain_short_rmse"] = number((*adain)["short"], "rmse");
  return r;
}

void check(RunSummary& s, const char* name, double value, double limit, bool at_most) {
  const bool ok = std::isfinite(value) && (at_most ? value <= limit : value >= limit);
  s.json["checks"].push_back({{"name", name}, {"value", value}, {"limit", limit}, {"at_most", at_most}, {"ok", ok}});
  if (!ok)
    s.failures.push_back(std::string(name) + " = " + fmt(value, 4) + (at_most ? " (at most " : " (at least ") +
                         fmt(limit, 4) + ")");
}

std::string page(const RunReportInput& in, const json& sum, const json& videos, const json& eval) {
  const fs::path out(in.out);
  std::ostringstream h;
  h << "<!doctype html>\n<html><head><meta charset=\"utf-8\"><title>stylerf run: " << html_escape(stem(in.scene))
    << "</title>\n<style>body{font-family:sans-serif;max-width:1200px;margin:auto;padding:1em}"
       "table{border-collapse:collapse}td,th{border:1px solid #bbb;padding:3px 8px;text-align:right}"
       "th{background:#eee}img,video{max-width:100%}figure{display:inline-block;margin:6px}"
       ".sheet{width:540px}.frame{width:320px}.grid{width:640px}"
       ".bad{color:#b00;font-weight:bold}.ok{color:#070}</style></head><body>\n";
  h << "<h1>StyleRF on " << html_escape(in.scene) << "</h1>\n<p>recipe <b>" << html_escape(in.recipe)
    << "</b>; " << fmt(sum.value("total_seconds", 0.0) / 60.0, 1) << " minutes in all.</p>\n";
  h << "<h2>Stages</h2>\n<table><tr><th>step</th><th>seconds</th><th>peak memory (MB)</th><th>held-out PSNR "
       "(dB)</th></tr>\n";
  // In the order the steps run (the record is a JSON object, which keeps its keys sorted).
  std::vector<std::string> order = {"density", "features",   "density_test", "features_test", "probe_style",
                                    "probe_frames", "style", "style_eval", "videos", "mix", "consistency"};
  for (const auto& [name, st] : in.steps.items())
    if (std::find(order.begin(), order.end(), name) == order.end()) order.push_back(name);
  for (const auto& name : order) {
    if (!in.steps.contains(name)) continue;
    const json& st = in.steps.at(name);
    std::string psnr;
    if (name == "density" || name == "features")
      psnr = fmt(sum["stages"][name].value("test_psnr", std::nan("")), 2);
    h << "<tr><td style=\"text-align:left\">" << html_escape(name) << "</td><td>" << fmt(st.value("seconds", 0.0), 1)
      << "</td><td>" << fmt(st.value("peak_rss_mb", std::nan("")), 0) << "</td><td>" << psnr << "</td></tr>\n";
  }
  h << "</table>\n";
  if (in.plan.is_object()) {
    h << "<p>Time plan: a frame of this scene costs " << fmt(number(in.plan, "frame_content_s"), 2)
      << " s of content and " << fmt(number(in.plan, "frame_style_s"), 2) << " s a style here (probe_*), an RGB "
      << "view of the density stage " << fmt(number(in.plan, "frame_rgb_s"), 2) << " s (density_test); the "
      << "evaluation was predicted at " << fmt(number(in.plan, "predicted_eval_s") / 60.0, 1)
      << " min, the style stage ";
    if (in.plan.contains("style_iters"))
      h << "trained its " << in.plan["style_iters"].get<int>() << " iterations (--stage-iters).";
    else
      h << "given " << fmt(number(in.plan, "style_minutes"), 1) << " min.";
    for (const char* k : {"cuts", "late_cuts"})
      if (!in.plan.value(k, std::string()).empty())
        h << " To fit the budget: " << html_escape(in.plan.value(k, std::string())) << ".";
    h << "</p>\n";
  }
  h << "<h2>Checks</h2>\n<table><tr><th>measure</th><th>value</th><th>limit</th><th></th></tr>\n";
  for (const auto& c : sum["checks"])
    h << "<tr><td style=\"text-align:left\">" << html_escape(c.value("name", "")) << "</td><td>"
      << fmt(number(c, "value"), 4) << "</td><td>" << (c.value("at_most", true) ? "&le; " : "&ge; ")
      << fmt(number(c, "limit"), 3) << "</td><td class=\"" << (c.value("ok", false) ? "ok\">ok" : "bad\">fails")
      << "</td></tr>\n";
  h << "</table>\n<h2>Held-out styles: truth | StyleRF | 2D AdaIN (first test view)</h2>\n<p>Style loss over 2D "
       "AdaIN's, by the same VGG: <b>"
    << fmt(number(sum, "style_loss_ratio"), 3) << "x</b> on average (content " << fmt(number(sum, "content_loss_ratio"), 3)
    << "x).</p>\n";
  for (const auto& r : eval.value("styles", json::array())) {
    const std::string st = r.value("style", "");
    h << "<figure><img class=\"sheet\" src=\"style_eval/" << html_escape(st) << ".png\"><figcaption>" << html_escape(st)
      << ": style loss " << fmt(number(r, "style_ratio"), 2) << "x AdaIN's</figcaption></figure>\n";
  }
  h << "<h2>Zero-shot videos</h2>\n";
  const auto& outputs = videos.value("outputs", json::array());
  for (size_t i = 0; i < outputs.size(); ++i) {
    const std::string dir = outputs[i].value("dir", "");
    const std::string style = i < in.shown_styles.size() ? in.shown_styles[i] : outputs[i].value("name", "");
    h << "<figure><video class=\"frame\" controls loop autoplay muted src=\"" << html_escape(link(out, dir + "/video.mp4"))
      << "\"></video><figcaption>" << html_escape(stem(style)) << " <img src=\"" << html_escape(link(out, style))
      << "\" style=\"height:48px;vertical-align:middle\"></figcaption></figure>\n";
  }
  h << "<h2>Style interpolation (corners: ";
  for (size_t i = 0; i < in.corners.size(); ++i) h << (i ? ", " : "") << html_escape(stem(in.corners[i]));
  h << ")</h2>\n<img class=\"grid\" src=\"mix/mix_grid.png\">\n";
  h << "<h2>Consistency against per-frame 2D AdaIN</h2>\n<p>StyleRF / AdaIN: short-range RMSE <b>"
    << fmt(number(sum["consistency"], "short_rmse_ratio"), 3) << "x</b>, long-range RMSE "
    << fmt(number(sum["consistency"], "long_rmse_ratio"), 3) << "x, short-range LPIPS ("
    << html_escape(sum["consistency"].value("lpips_net", std::string("none"))) << ") "
    << fmt(number(sum["consistency"], "short_lpips_ratio"), 3) << "x, long-range LPIPS "
    << fmt(number(sum["consistency"], "long_lpips_ratio"), 3)
    << "x (the paper: RMSE 0.67x short, 0.74x long). Full table: <a href=\"consistency/table.md\">table.md</a>.</p>\n";
  for (const auto& e : fs::directory_iterator(out / "consistency")) {
    if (!e.is_directory()) continue;
    const std::string scene = e.path().filename().string();
    h << "<figure><video class=\"sheet\" controls loop autoplay muted src=\"consistency/" << html_escape(scene)
      << "/side_by_side/side_by_side.mp4\"></video><figcaption>AdaIN per frame | StyleRF</figcaption></figure>\n"
      << "<figure><img src=\"consistency/" << html_escape(scene)
      << "/per_frame_rmse.svg\"><figcaption>short-range RMSE per frame pair</figcaption></figure>\n";
  }
  h << "<p>Numbers: <a href=\"summary.json\">summary.json</a>; logs: <a href=\"logs/\">logs/</a>.</p>\n</body></html>\n";
  return h.str();
}

}  // namespace

RunSummary write_run_report(const RunReportInput& in, const RunLimits& limits) {
  const fs::path out(in.out);
  RunSummary s;
  json& j = s.json;
  j["recipe"] = in.recipe;
  j["scene"] = in.scene;
  j["training_minutes"] = in.minutes;
  j["steps"] = in.steps;
  if (in.plan.is_object()) j["plan"] = in.plan;
  double total = 0;
  for (const auto& [name, st] : in.steps.items()) total += st.value("seconds", 0.0);
  j["total_seconds"] = total;
  const json dt = read_json(out / "density_test/metrics.json"), ft = read_json(out / "features_test/metrics.json");
  j["stages"]["density"] = {{"seconds", in.steps.value("density", json::object()).value("seconds", 0.0)},
                            {"test_psnr", number(dt, "mean_psnr")}};
  j["stages"]["features"] = {{"seconds", in.steps.value("features", json::object()).value("seconds", 0.0)},
                             {"test_psnr", number(ft, "mean_psnr")}};
  j["stages"]["style"] = {{"seconds", in.steps.value("style", json::object()).value("seconds", 0.0)}};
  for (const char* st : {"density", "features", "style"})
    j["stages"][st]["peak_rss_mb"] = in.steps.value(st, json::object()).value("peak_rss_mb", std::nan(""));
  const json eval = read_json(out / "style_eval.json");
  j["style_loss_ratio"] = number(eval, "style_loss_ratio");
  j["content_loss_ratio"] = number(eval, "content_loss_ratio");
  double worst = 0;
  j["per_style"] = json::array();
  for (const auto& r : eval.value("styles", json::array())) {
    j["per_style"].push_back({{"style", r.value("style", "")}, {"style_ratio", number(r, "style_ratio")}});
    worst = std::max(worst, number(r, "style_ratio"));
  }
  j["max_style_loss_ratio"] = worst;
  j["mix_corner_min_mean_abs_diff"] = number(read_json(out / "mix/metrics.json"), "corner_min_mean_abs_diff");
  j["consistency"] = consistency_ratios(read_json(out / "consistency/table.json"));
  j["checks"] = json::array();
  check(s, "held-out style loss / 2D AdaIN's", number(j, "style_loss_ratio"), limits.style_loss_ratio, true);
  check(s, "mix-sheet closest corners, mean abs difference", number(j, "mix_corner_min_mean_abs_diff"),
        limits.mix_corner_min, false);
  check(s, "short-range RMSE / per-frame AdaIN's", number(j["consistency"], "short_rmse_ratio"),
        limits.short_rmse_ratio, true);
  const json videos = read_json(out / "videos/metrics.json");
  host::write_file_atomic((out / "summary.json").string(), j.dump(2) + "\n");
  host::write_file_atomic((out / "index.html").string(), page(in, j, videos, eval));
  return s;
}

void print_run_summary(const RunSummary& s, std::ostream& os) {
  const json& j = s.json;
  os << "\n== summary\n"
     << "  density: " << fmt(j["stages"]["density"].value("test_psnr", std::nan("")), 2) << " dB held out; features "
     << "(decoded): " << fmt(j["stages"]["features"].value("test_psnr", std::nan("")), 2) << " dB\n"
     << "  held-out style loss / 2D AdaIN's: " << fmt(number(j, "style_loss_ratio"), 3) << "x (worst style "
     << fmt(number(j, "max_style_loss_ratio"), 2) << "x)\n"
     << "  consistency, StyleRF / per-frame AdaIN: short RMSE " << fmt(number(j["consistency"], "short_rmse_ratio"), 3)
     << "x, short LPIPS (" << j["consistency"].value("lpips_net", std::string("none")) << ") "
     << fmt(number(j["consistency"], "short_lpips_ratio"), 3) << "x\n"
     << "  mix sheet: closest corners differ by " << fmt(number(j, "mix_corner_min_mean_abs_diff"), 4) << "\n";
  for (const auto& c : j["checks"])
    os << "  [" << (c.value("ok", false) ? "ok" : "FAILS") << "] " << c.value("name", "") << "\n";
  os << "  " << fmt(number(j, "total_seconds") / 60.0, 1) << " minutes; open " << "index.html in the output folder"
     << std::endl;
}

}  // namespace stylerf::cli
