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

// The scene's name: its folder's ("lego" of "data/nerf_synthetic/lego/").
std::string scene_name(const std::string& scene) {
  const fs::path p = fs::path(scene).lexically_normal();
  const std::string name = p.filename().empty() ? p.parent_path().filename().string() : p.filename().string();
  return name.empty() ? scene : name;
}

// A style image of the folder `styles` whose name (without its extension) is `stem`; "" when none is.
std::string style_image(const std::string& styles, const std::string& stem) {
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(styles, ec))
    if (e.is_regular_file() && e.path().stem() == stem) return e.path().string();
  return "";
}

// An image that opens at full size when clicked.
std::string linked_image(const std::string& src, const char* css_class) {
  return "<a href=\"" + html_escape(src) + "\"><img class=\"" + css_class + "\" src=\"" + html_escape(src) + "\"></a>";
}

void page_head(std::ostringstream& h, const RunReportInput& in, const json& sum) {
  const std::string name = html_escape(scene_name(in.scene));
  h << "<!doctype html>\n<html><head><meta charset=\"utf-8\"><title>StyleRF: " << name
    << "</title>\n<style>body{font-family:sans-serif;max-width:1200px;margin:auto;padding:1em}"
       "table{border-collapse:collapse}td,th{border:1px solid #bbb;padding:3px 8px;text-align:right}"
       "th{background:#eee}td.name{text-align:left}img,video{max-width:100%}figure{display:inline-block;"
       "margin:6px;vertical-align:top}.sheet{height:200px}.frame{width:320px}.grid{width:640px}"
       ".view{width:200px;image-rendering:pixelated}.style{height:200px}.thumb{height:48px;vertical-align:middle}"
       ".note{color:#555}.bad{color:#b00;font-weight:bold}.ok{color:#070}</style></head><body>\n";
  h << "<h1>StyleRF: " << name << "</h1>\n<p>Scene <code>" << html_escape(in.scene) << "</code>, recipe <b>"
    << html_escape(in.recipe) << "</b>; " << fmt(sum.value("total_seconds", 0.0) / 60.0, 1)
    << " minutes in all. How it was made: <a href=\"#provenance\">below</a>.</p>\n";
}

// The three training stages with their held-out PSNR, then every step's time and memory.
void stages_section(std::ostringstream& h, const RunReportInput& in, const json& sum) {
  h << "<h2>Stages</h2>\n<table><tr><th>stage</th><th>seconds</th><th>held-out PSNR (dB, higher is "
       "better)</th></tr>\n";
  for (const char* stage : {"density", "features", "style"}) {
    const json& st = sum["stages"][stage];
    const double psnr = st.value("test_psnr", std::nan(""));
    h << "<tr><td class=\"name\">" << stage << (std::string(stage) == "features" ? " (decoded views)" : "")
      << "</td><td>" << fmt(st.value("seconds", 0.0), 1) << "</td><td>"
      << (std::isfinite(psnr) ? fmt(psnr, 2) : "not measured (styles have no ground truth)") << "</td></tr>\n";
  }
  h << "</table>\n<h3>Time per step</h3>\n<table><tr><th>step</th><th>seconds</th><th>peak memory (MB)</th></tr>\n";
  // In the order the steps run (the record is a JSON object, which keeps its keys sorted).
  std::vector<std::string> order = {"density", "features",   "density_test", "features_test", "probe_style",
                                    "probe_frames", "style", "style_eval", "videos", "mix", "consistency"};
  for (const auto& [name, st] : in.steps.items())
    if (std::find(order.begin(), order.end(), name) == order.end()) order.push_back(name);
  for (const auto& name : order) {
    if (!in.steps.contains(name)) continue;
    const json& st = in.steps.at(name);
    h << "<tr><td class=\"name\">" << html_escape(name) << "</td><td>" << fmt(st.value("seconds", 0.0), 1)
      << "</td><td>" << fmt(st.value("peak_rss_mb", std::nan("")), 0) << "</td></tr>\n";
  }
  h << "</table>\n";
}

void plan_paragraph(std::ostringstream& h, const json& plan) {
  if (!plan.is_object()) return;
  h << "<p>Time plan: a frame of this scene costs " << fmt(number(plan, "frame_content_s"), 2)
    << " s of content and " << fmt(number(plan, "frame_style_s"), 2) << " s a style here (probe_*), an RGB "
    << "view of the density stage " << fmt(number(plan, "frame_rgb_s"), 2) << " s (density_test); the "
    << "evaluation was predicted at " << fmt(number(plan, "predicted_eval_s") / 60.0, 1) << " min, the style stage ";
  if (plan.contains("style_iters"))
    h << "trained its " << plan["style_iters"].get<int>() << " iterations (--stage-iters).";
  else
    h << "given " << fmt(number(plan, "style_minutes"), 1) << " min.";
  for (const char* k : {"cuts", "late_cuts"})
    if (!plan.value(k, std::string()).empty()) h << " To fit the budget: " << html_escape(plan.value(k, std::string())) << ".";
  h << "</p>\n";
}

void checks_section(std::ostringstream& h, const json& sum) {
  h << "<h2>Checks</h2>\n<table><tr><th>measure</th><th>value</th><th>limit</th><th></th></tr>\n";
  for (const auto& c : sum["checks"]) {
    const bool at_most = c.value("at_most", true);
    h << "<tr><td class=\"name\">" << html_escape(c.value("name", ""))
      << (at_most ? " (lower is better)" : " (higher is better)") << "</td><td>" << fmt(number(c, "value"), 4)
      << "</td><td>" << (at_most ? "&le; " : "&ge; ") << fmt(number(c, "limit"), 3) << "</td><td class=\""
      << (c.value("ok", false) ? "ok\">ok" : "bad\">fails") << "</td></tr>\n";
  }
  h << "</table>\n";
}

// Each held-out test view: the photograph, the density stage's RGB and the feature stage's decoded view.
void test_views_section(std::ostringstream& h, const fs::path& out, const json& density_test, const json& features_test) {
  h << "<h2>Held-out test views: truth | density (RGB) | decoded features</h2>\n";
  const json rgb_views = density_test.value("views", json::array());
  for (const auto& v : features_test.value("views", json::array())) {
    const json* rgb = nullptr;
    for (const auto& d : rgb_views)
      if (d.value("view", -1) == v.value("view", -2)) rgb = &d;
    h << "<figure>" << linked_image(link(out, v.value("source", "")), "view");
    if (rgb) h << linked_image("density_test/" + rgb->value("image", ""), "view");
    h << linked_image("features_test/" + v.value("image", ""), "view") << "<figcaption>view " << v.value("view", 0)
      << ": PSNR";
    if (rgb) h << " density " << fmt(number(*rgb, "psnr"), 2) << " dB,";
    h << " decoded " << fmt(number(v, "psnr"), 2) << " dB (higher is better)</figcaption></figure>\n";
  }
}

void style_eval_section(std::ostringstream& h, const RunReportInput& in, const json& sum, const json& eval) {
  const fs::path out(in.out);
  h << "<h2>Held-out styles: truth | StyleRF | 2D AdaIN (first test view), and the style</h2>\n<p>Style loss over "
       "2D AdaIN's, by the same VGG (lower is better): <b>"
    << fmt(number(sum, "style_loss_ratio"), 3) << "x</b> on average (content loss " << fmt(number(sum, "content_loss_ratio"), 3)
    << "x; LPIPS to the true view, the structure kept, " << fmt(number(sum, "structure_lpips_ratio"), 3)
    << "x; lower is better for all three).</p>\n";
  for (const auto& r : eval.value("styles", json::array())) {
    const std::string st = r.value("style", ""), image = style_image(in.styles, st);
    h << "<figure>" << linked_image("style_eval/" + st + ".png", "sheet");
    if (!image.empty()) h << linked_image(link(out, image), "style");
    h << "<figcaption>" << html_escape(st) << ": over AdaIN's, style loss " << fmt(number(r, "style_ratio"), 2)
      << "x, content loss " << fmt(number(r, "content_ratio"), 2) << "x, LPIPS to the truth "
      << fmt(number(r, "structure_lpips_ratio"), 2) << "x (lower is better)</figcaption></figure>\n";
  }
}

void videos_section(std::ostringstream& h, const RunReportInput& in, const json& videos) {
  const fs::path out(in.out);
  h << "<h2>Zero-shot videos</h2>\n";
  const auto& outputs = videos.value("outputs", json::array());
  for (size_t i = 0; i < outputs.size(); ++i) {
    const std::string dir = outputs[i].value("dir", "");
    const std::string style = i < in.shown_styles.size() ? in.shown_styles[i] : outputs[i].value("name", "");
    h << "<figure><video class=\"frame\" controls loop autoplay muted src=\"" << html_escape(link(out, dir + "/video.mp4"))
      << "\"></video><figcaption>" << html_escape(stem(style)) << " <img class=\"thumb\" src=\""
      << html_escape(link(out, style)) << "\"></figcaption></figure>\n";
  }
  h << "<h2>Style interpolation (corners: ";
  for (size_t i = 0; i < in.corners.size(); ++i) h << (i ? ", " : "") << html_escape(stem(in.corners[i]));
  h << ")</h2>\n<img class=\"grid\" src=\"mix/mix_grid.png\">\n";
}

void consistency_section(std::ostringstream& h, const fs::path& out, const json& sum) {
  const json& c = sum["consistency"];
  h << "<h2>Consistency against per-frame 2D AdaIN</h2>\n<p>StyleRF / AdaIN, lower is better: short-range RMSE <b>"
    << fmt(number(c, "short_rmse_ratio"), 3) << "x</b>, long-range RMSE " << fmt(number(c, "long_rmse_ratio"), 3)
    << "x, short-range LPIPS (" << html_escape(c.value("lpips_net", std::string("none"))) << ") "
    << fmt(number(c, "short_lpips_ratio"), 3) << "x, long-range LPIPS " << fmt(number(c, "long_lpips_ratio"), 3)
    << "x (the paper, Table 1: RMSE 0.67x short, 0.74x long; LPIPS 0.47x short, 0.68x long). Full table: "
       "<a href=\"consistency/table.md\">table.md</a>.</p>\n";
  for (const auto& e : fs::directory_iterator(out / "consistency")) {
    if (!e.is_directory()) continue;
    const std::string scene = e.path().filename().string();
    h << "<figure><video class=\"sheet\" controls loop autoplay muted src=\"consistency/" << html_escape(scene)
      << "/side_by_side/side_by_side.mp4\"></video><figcaption>AdaIN per frame | StyleRF</figcaption></figure>\n"
      << "<figure><img src=\"consistency/" << html_escape(scene)
      << "/per_frame_rmse.svg\"><figcaption>short-range RMSE per frame pair (lower is better)</figcaption></figure>\n";
  }
}

// Escaped text whose lines break only between words (a browser would break "--eval-views" after its "--").
std::string unbroken_words(const std::string& text) {
  std::string o, word;
  std::istringstream in(text);
  while (in >> word) o += (o.empty() ? "" : " ") + ("<span style=\"white-space:nowrap\">" + html_escape(word) + "</span>");
  return o;
}

// What made the run: enough to tell it from another and to run it again.
void provenance_section(std::ostringstream& h, const RunReportInput& in) {
  const json& d = in.device;
  h << "<h2 id=\"provenance\">How it was made</h2>\n<table>"
    << "<tr><td class=\"name\">command</td><td class=\"name\"><code>" << unbroken_words(in.command_line) << "</code></td></tr>"
    << "<tr><td class=\"name\">device</td><td class=\"name\">" << html_escape(d.value("name", std::string("?")))
    << " (" << html_escape(d.value("type", std::string("?"))) << ", " << html_escape(d.value("platform", std::string("?")))
    << " " << html_escape(d.value("driver", std::string())) << ")</td></tr>"
    << "<tr><td class=\"name\">stylerf</td><td class=\"name\">" << html_escape(in.build.value("version", std::string("?")))
    << ", commit " << html_escape(in.build.value("commit", std::string("?"))) << "</td></tr>"
    << "<tr><td class=\"name\">recipe</td><td class=\"name\">" << html_escape(in.recipe)
    << "<details><summary>its settings</summary><pre>" << html_escape(in.recipe_settings.dump(2))
    << "</pre></details></td></tr></table>\n";
}

std::string page(const RunReportInput& in, const json& sum, const json& videos, const json& eval) {
  const fs::path out(in.out);
  std::ostringstream h;
  page_head(h, in, sum);
  stages_section(h, in, sum);
  plan_paragraph(h, in.plan);
  checks_section(h, sum);
  test_views_section(h, out, read_json(out / "density_test/metrics.json"), read_json(out / "features_test/metrics.json"));
  style_eval_section(h, in, sum, eval);
  videos_section(h, in, videos);
  consistency_section(h, out, sum);
  provenance_section(h, in);
  h << "<p>Numbers: <a href=\"summary.json\">summary.json</a>; logs: <a href=\"logs/\">logs/</a>.</p>\n</body></html>\n";
  return h.str();
}

}  // namespace

RunSummary write_run_report(const RunReportInput& in, const RunLimits& limits) {
  const fs::path out(in.out);
  RunSummary s;
  json& j = s.json;
  j["recipe"] = in.recipe;
  j["recipe_settings"] = in.recipe_settings;
  j["scene"] = in.scene;
  j["scene_name"] = scene_name(in.scene);
  j["command_line"] = in.command_line;
  j["device"] = in.device;
  j["build"] = in.build;
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
  // Style and content together: a low style loss bought by painting over the object shows in the other two.
  j["style_loss_ratio"] = number(eval, "style_loss_ratio");
  j["content_loss_ratio"] = number(eval, "content_loss_ratio");
  j["structure_lpips_ratio"] = number(eval, "structure_lpips_ratio");
  j["structure_lpips_net"] = eval.value("structure_lpips_net", std::string());
  // The largest measured value (NaN when none was: a score not measured is not a perfect one).
  auto raise = [](double& worst, double v) {
    if (std::isfinite(v) && !(worst >= v)) worst = v;
  };
  double worst_style = std::nan(""), worst_content = std::nan(""), worst_lpips = std::nan("");
  j["per_style"] = json::array();
  for (const auto& r : eval.value("styles", json::array())) {
    j["per_style"].push_back({{"style", r.value("style", "")},
                              {"style_ratio", number(r, "style_ratio")},
                              {"content_ratio", number(r, "content_ratio")},
                              {"structure_lpips_ratio", number(r, "structure_lpips_ratio")}});
    raise(worst_style, number(r, "style_ratio"));
    raise(worst_content, number(r, "content_ratio"));
    raise(worst_lpips, number(r, "structure_lpips_ratio"));
  }
  j["max_style_loss_ratio"] = worst_style;
  j["max_content_loss_ratio"] = worst_content;
  j["max_structure_lpips_ratio"] = worst_lpips;
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
     << "  held-out styles / 2D AdaIN's (lower is better): style loss " << fmt(number(j, "style_loss_ratio"), 3)
     << "x (worst " << fmt(number(j, "max_style_loss_ratio"), 2) << "x), content loss "
     << fmt(number(j, "content_loss_ratio"), 3) << "x (worst " << fmt(number(j, "max_content_loss_ratio"), 2)
     << "x), LPIPS to the true view " << fmt(number(j, "structure_lpips_ratio"), 3) << "x (worst "
     << fmt(number(j, "max_structure_lpips_ratio"), 2) << "x)\n"
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
