// `stylerf bench render`: ray throughput of a density checkpoint on its scene, for rendering held-out views
// and for training steps at the trainer's batch, with a per-kernel breakdown of where the time goes, and
// the same figures for each setting of the ray-cost knobs asked for (--ert: early-termination threshold).
// Rendering and training use the library's own paths (render_view, DensityTrainer::step), so what this
// prints is what `render` and `train-density` pay.
#include <algorithm>
#include <chrono>
#include <iomanip>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>

#include "bench/bench.hpp"
#include "host/error.hpp"
#include "host/files.hpp"
#include "host/runtime.hpp"
#include "lib/io/checkpoint.hpp"
#include "lib/scene/scene_meta.hpp"
#include "lib/train/density_trainer.hpp"

namespace stylerf::bench {

using nlohmann::json;

namespace {

double now_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// Per-kernel device milliseconds since the last reset, largest first.
std::vector<std::pair<std::string, double>> kernel_breakdown() {
  std::vector<std::pair<std::string, double>> v;
  for (const auto& k : host::Runtime::instance().timings()) v.emplace_back(k.kernel, k.total_ms);
  std::sort(v.begin(), v.end(), [](const auto& a, const auto& b) { return a.second > b.second; });
  return v;
}

json print_breakdown(const std::vector<std::pair<std::string, double>>& v, double per, const char* unit) {
  double total = 0;
  for (const auto& k : v) total += k.second;
  json j = json::object();
  std::cout << "    kernels (" << unit << "; share of kernel time):\n";
  for (size_t i = 0; i < v.size(); ++i) {
    j[v[i].first] = v[i].second / per / 1e3;
    if (i < 12)
      std::cout << "      " << std::left << std::setw(26) << v[i].first << std::right << std::fixed << std::setprecision(3)
                << std::setw(9) << v[i].second / per / 1e3 << " s  " << std::setprecision(1) << std::setw(5)
                << 100.0 * v[i].second / std::max(1e-9, total) << "%\n";
  }
  return j;
}

struct RenderFigures {
  double s_per_view = 0, rays_per_s = 0, psnr = 0;
};

RenderFigures time_render(const model::DensityModel& m, const scene::Scene& sc, int views, json& out) {
  auto& rt = host::Runtime::instance();
  const int n = static_cast<int>(sc.test.size());
  views = std::min(views, n);
  // One small render first: kernels compile outside the timed views.
  {
    scene::Camera c = sc.test[0].camera;
    c.width = std::min(c.width, 16);
    c.height = std::min(c.height, 16);
    model::render_view(m, sc, c);
  }
  rt.finish();
  rt.reset_timings();
  rt.set_profiling(true);
  double seconds = 0, psnr = 0;
  int64_t rays = 0;
  for (int i = 0; i < views; ++i) {
    const int id = views == 1 ? 0 : int(int64_t(i) * (n - 1) / (views - 1));
    const auto& v = sc.test[size_t(id)];
    const double t0 = now_s();
    const auto r = model::render_view(m, sc, v.camera);
    rt.finish();
    const double s = now_s() - t0;
    seconds += s;
    rays += int64_t(v.camera.width) * v.camera.height;
    double se = 0;
    for (size_t k = 0; k < r.value.size(); ++k) {
      const double d = double(r.value[k]) - v.rgb[k];
      se += d * d;
    }
    const double p = -10.0 * std::log10(std::max(1e-12, se / double(r.value.size())));
    psnr += p;
    std::cout << "    view " << id << ": " << std::fixed << std::setprecision(2) << s << " s, PSNR " << p << " dB\n";
  }
  rt.set_profiling(false);
  RenderFigures f;
  f.s_per_view = seconds / views;
  f.rays_per_s = double(rays) / seconds;
  f.psnr = psnr / views;
  std::cout << "    render: " << std::setprecision(2) << f.s_per_view << " s/view, " << std::setprecision(0)
            << f.rays_per_s << " rays/s, PSNR " << std::setprecision(2) << f.psnr << " dB over " << views
            << " views\n";
  out = {{"views", views}, {"s_per_view", f.s_per_view}, {"rays_per_s", f.rays_per_s}, {"psnr", f.psnr}};
  out["kernel_s_per_view"] = print_breakdown(kernel_breakdown(), views, "s per view");
  return f;
}

void time_training(const scene::Scene& sc, const io::Checkpoint& ck, float ert, int steps, json& out) {
  train::DensityTrainer tr(sc, ck);
  tr.model().geo.ert_threshold = ert;
  tr.set_total_iters(tr.iteration() + steps + 1);
  auto& rt = host::Runtime::instance();
  tr.step();  // warm-up: kernels compile, buffers are pooled
  rt.finish();
  rt.reset_timings();
  rt.set_profiling(true);
  double seconds = 0, samples = 0, kept = 0, mse = 0;
  std::vector<double> each;
  for (int i = 0; i < steps; ++i) {
    const double t0 = now_s();
    const auto st = tr.step();
    rt.finish();
    const double s = now_s() - t0;  // the queue drained: the step's whole time
    each.push_back(s);
    seconds += s;
    samples += double(st.samples);
    kept += double(st.kept);
    mse += st.mse;
  }
  rt.set_profiling(false);
  const int batch = tr.config().batch;
  std::sort(each.begin(), each.end());
  const double mean = seconds / steps, median = each[each.size() / 2];
  std::cout << "    train: " << std::fixed << std::setprecision(3) << mean << " s/step mean, " << median
            << " s median, " << std::setprecision(0) << batch / mean << " rays/s, " << std::setprecision(1)
            << samples / (double(steps) * batch) << " samples/ray (kept " << 100.0 * kept / std::max(1.0, samples)
            << "%), batch PSNR " << std::setprecision(2) << -10.0 * std::log10(std::max(1e-12, mse / steps))
            << " dB\n";
  out = {{"steps", steps},
         {"batch", batch},
         {"s_per_step", mean},
         {"s_per_step_median", median},
         {"rays_per_s", batch / mean},
         {"samples_per_ray", samples / (double(steps) * batch)},
         {"kept_fraction", kept / std::max(1.0, samples)}};
  out["kernel_s_per_step"] = print_breakdown(kernel_breakdown(), steps, "s per step");
}

}  // namespace

int bench_render(const BenchOptions& opt) {
  if (opt.ckpt.empty()) throw host::Error("bench render: --ckpt (a density checkpoint) is required");
  const auto ck = io::load_checkpoint(opt.ckpt, "density");
  const json smeta = ck.meta.value("scene", json::object());
  scene::SceneOverrides o;
  o.dir = opt.scene;
  const auto sc = scene::open_scene_for(smeta, opt.ckpt, o).scene;
  if (sc.test.empty()) throw host::Error("bench render: scene " + sc.root + " has no held-out views");
  const int views = opt.quick ? 1 : opt.views, steps = opt.quick ? 2 : opt.steps;
  model::DensityModel m = model::load_model(ck);
  std::vector<float> erts = opt.erts;
  if (erts.empty()) erts.push_back(m.geo.ert_threshold);  // the scene's default
  std::cout << "bench render: " << opt.ckpt << " on " << sc.root << " (" << sc.train.size() << " train, "
            << sc.test.size() << " test views, " << sc.test[0].camera.width << "x" << sc.test[0].camera.height
            << ")\n  " << m.describe() << "\n";
  json rows = json::array();
  for (float ert : erts) {
    std::cout << "  early termination " << (ert > 0 ? "below transmittance " + std::to_string(ert) : "off") << ":\n";
    m.geo.ert_threshold = ert;
    json row = {{"ert_threshold", ert}};
    time_render(m, sc, views, row["render"]);
    if (steps > 0) {
      if (ck.meta.contains("trainer"))
        time_training(sc, ck, ert, steps, row["train"]);
      else
        std::cout << "    train: skipped (the checkpoint holds no trainer state)\n";
    }
    rows.push_back(row);
  }
  if (!opt.json_path.empty()) {
    json doc = {{"bench", "render"}, {"ckpt", opt.ckpt}, {"scene", sc.root},
                {"device", host::Runtime::instance().device().name}, {"rows", rows}};
    host::write_file_atomic(opt.json_path, doc.dump(2) + "\n");
    std::cout << "wrote " << opt.json_path << "\n";
  }
  return 0;
}

}  // namespace stylerf::bench
