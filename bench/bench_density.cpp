#include "bench/bench_density.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <iomanip>
#include <iostream>
#include <nlohmann/json.hpp>

#include "host/error.hpp"
#include "host/files.hpp"
#include "host/runtime.hpp"
#include "lib/io/image.hpp"
#include "lib/train/density_trainer.hpp"

namespace stylerf::bench {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

std::string data_dir() {
  if (const char* e = std::getenv("STYLERF_DATA")) return e;
  for (const char* d : {"../shared/data", "../../shared/data"})
    if (fs::is_directory(fs::path(d) / "scenes")) return d;
  throw host::Error("bench density: scene data not found; set STYLERF_DATA to the folder holding scenes/");
}

struct CurvePoint {
  int iteration;
  double seconds, psnr;
};

struct RunResult {
  std::vector<CurvePoint> curve;
  double s_per_it = 0, final_psnr = 0, seconds = 0;
  int iterations = 0;
  double samples_per_ray = 0;
};

// Trains for `budget_s` seconds of training time (eval excluded), evaluating `eval_views` held-out views
// `evals` times along the way. The schedule is refitted to the budget as the step rate becomes known
// (RunOptions::fit_schedule_to_budget), as `train-density --minutes` does.
RunResult timed_run(const scene::Scene& sc, train::DensityTrainConfig cfg, double budget_s, int eval_views, int evals,
                    const std::string& label) {
  {  // compile every kernel outside the timed run
    auto wc = cfg;
    wc.schedule = cfg.schedule.fitted(2, 1);
    train::DensityTrainer w(sc, wc);
    w.step();
  }
  train::DensityTrainer tr(sc, cfg);
  std::cout << "  " << label << ": " << budget_s << " s of training; schedule refitted to the budget as it runs"
            << std::endl;
  RunResult r;
  double train_s = 0, next_eval = budget_s / evals;
  int64_t samples = 0;
  auto eval_now = [&](int it) {
    const double p = train::mean_psnr(train::evaluate_views(tr.model(), sc, eval_views, false));
    r.curve.push_back({it, train_s, p});
    std::cout << "    it " << it << "  " << std::fixed << std::setprecision(1) << train_s << " s  PSNR "
              << std::setprecision(2) << p << " dB" << std::endl;
  };
  train::RunOptions ro;
  ro.time_budget_s = budget_s;
  ro.fit_schedule_to_budget = true;
  ro.log = &std::cout;
  ro.log_every = 0;  // refits and events only
  ro.after_step = [&](const train::StepStats& st) {
    train_s += st.seconds;
    samples += st.samples;
    if (train_s >= next_eval && !tr.done() && train_s < budget_s) {
      eval_now(st.iteration);
      next_eval += budget_s / evals;
    }
    return true;
  };
  const auto sum = train::run_density_training(tr, ro);
  eval_now(tr.iteration());
  r.iterations = sum.iterations;
  r.seconds = sum.seconds;
  r.s_per_it = sum.seconds / std::max(1, sum.iterations);
  r.final_psnr = r.curve.back().psnr;
  r.samples_per_ray = double(samples) / (double(std::max(1, sum.iterations)) * cfg.batch);
  return r;
}

// ---- plot ----------------------------------------------------------------------------------------------
void line(io::Image& img, double x0, double y0, double x1, double y1, const float rgb[3], int dash = 0) {
  const int n = int(std::max(std::abs(x1 - x0), std::abs(y1 - y0))) + 1;
  for (int i = 0; i <= n; ++i) {
    if (dash > 0 && (i / dash) % 2) continue;
    const double t = double(i) / n;
    const int x = int(std::lround(x0 + (x1 - x0) * t)), y = int(std::lround(y0 + (y1 - y0) * t));
    for (int dy = 0; dy <= 1; ++dy)
      for (int dx = 0; dx <= 1; ++dx) {
        const int xx = x + dx, yy = y + dy;
        if (xx < 0 || yy < 0 || xx >= img.width || yy >= img.height) continue;
        for (int c = 0; c < 3; ++c) img.at(c, yy, xx) = rgb[c];
      }
  }
}

// PSNR (y, 10..35 dB, grid every 5 dB) against training seconds (x, 0..max); solid curves per scene,
// dashed lines at the targets (lego 28 dB red, fern 22 dB blue).
void plot(const std::string& path, const std::vector<std::pair<std::string, RunResult>>& runs, double max_s) {
  io::Image img;
  img.width = 640;
  img.height = 400;
  img.data.assign(size_t(3) * img.width * img.height, 1.0f);
  const double L = 50, R = 620, T = 20, B = 370, y_lo = 10, y_hi = 35;
  auto X = [&](double s) { return L + (R - L) * s / std::max(max_s, 1e-9); };
  auto Y = [&](double p) { return B - (B - T) * (std::clamp(p, y_lo, y_hi) - y_lo) / (y_hi - y_lo); };
  const float grey[3] = {0.85f, 0.85f, 0.85f}, black[3] = {0, 0, 0};
  for (double p = y_lo; p <= y_hi; p += 5) line(img, L, Y(p), R, Y(p), grey);
  for (int k = 0; k <= 6; ++k) line(img, X(max_s * k / 6), T, X(max_s * k / 6), B, grey);
  line(img, L, B, R, B, black);
  line(img, L, T, L, B, black);
  const float colours[2][3] = {{0.85f, 0.15f, 0.1f}, {0.1f, 0.3f, 0.85f}};
  const double targets[2] = {28.0, 22.0};
  for (const auto& [name, run] : runs) {
    const int i = name == "lego" ? 0 : 1;
    line(img, L, Y(targets[i]), R, Y(targets[i]), colours[i], 6);
    const auto& c = run.curve;
    for (size_t k = 1; k < c.size(); ++k)
      line(img, X(c[k - 1].seconds), Y(c[k - 1].psnr), X(c[k].seconds), Y(c[k].psnr), colours[i]);
  }
  io::save_png(path, img);
}

}  // namespace

int bench_density(const BenchOptions& opt) {
  std::cout << "device: " << host::Runtime::instance().device().describe() << "\n";
  const std::string data = data_dir();
  const double budget = opt.budget_s > 0 ? opt.budget_s : opt.quick ? 240.0 : 1800.0;
  const double knob_budget = opt.knob_budget_s > 0 ? opt.knob_budget_s : opt.quick ? 60.0 : 300.0;
  const int eval_views = opt.quick ? 2 : 8, evals = opt.quick ? 3 : 12;
  auto wanted = [&](const std::string& part) {
    return opt.parts.empty() || std::find(opt.parts.begin(), opt.parts.end(), part) != opt.parts.end();
  };
  json doc{{"device", host::Runtime::instance().device().describe()},
           {"quick", opt.quick},
           {"budget_s", budget},
           {"knob_budget_s", knob_budget},
           {"eval_views", eval_views}};
  const fs::path base = opt.json_path.empty() ? fs::path(".") : fs::path(opt.json_path).parent_path();
  const std::string png = ((base.empty() ? fs::path(".") : base) / "density_psnr_vs_time.png").string();
  // Written after every part, so a long run stopped part-way keeps what it measured.
  auto save = [&] {
    if (!opt.json_path.empty()) host::write_file_atomic(opt.json_path, doc.dump(2) + "\n");
  };

  struct Spec {
    std::string name, dir;
    int downsample;
    double target;
    int evals;  // held-out evaluations along the curve (fern's views take ~1 min each before the mask)
  };
  const std::vector<Spec> specs = {{"lego", data + "/scenes/blender/lego", 4, 28.0, evals},
                                   {"fern", data + "/scenes/llff/fern", 8, 22.0, std::max(2, evals / 3)}};
  auto load = [&](const Spec& sp) {
    scene::LoadOptions lo;
    lo.downsample = sp.downsample;
    auto sc = std::make_unique<scene::Scene>(scene::load_scene(sp.dir, lo));
    std::cout << sp.name << " 1/" << sp.downsample << ": " << sc->width() << "x" << sc->height() << ", "
              << sc->train.size() << " train / " << sc->test.size() << " test views\n";
    return sc;
  };
  std::vector<std::pair<std::string, RunResult>> runs;
  std::unique_ptr<scene::Scene> lego;
  for (const auto& sp : specs) {
    if (!wanted(sp.name)) continue;
    auto sc = load(sp);
    const auto cfg = train::default_density_config(*sc);
    const auto r = timed_run(*sc, cfg, budget, eval_views, sp.evals, sp.name);
    json curve = json::array();
    for (const auto& p : r.curve) curve.push_back({{"iteration", p.iteration}, {"seconds", p.seconds}, {"psnr", p.psnr}});
    doc["scenes"][sp.name] = {{"downsample", sp.downsample},
                              {"target_psnr", sp.target},
                              {"iterations", r.iterations},
                              {"seconds", r.seconds},
                              {"s_per_iteration", r.s_per_it},
                              {"samples_per_ray", r.samples_per_ray},
                              {"final_psnr", r.final_psnr},
                              {"curve", curve}};
    std::cout << "  " << sp.name << ": " << r.iterations << " it in " << std::setprecision(0) << r.seconds << " s ("
              << std::setprecision(2) << 1.0 / r.s_per_it << " it/s), PSNR " << r.final_psnr << " dB (target "
              << sp.target << ")" << std::endl;
    runs.emplace_back(sp.name, r);
    plot(png, runs, budget);
    doc["plot"] = png;
    save();
    if (sp.name == "lego") lego = std::move(sc);
  }
  if (!runs.empty())
    std::cout << "plot: " << png << " (x: training seconds 0.." << budget
              << ", y: PSNR 10..35 dB; red lego, blue fern; dashed: targets)\n";
  if (!wanted("knobs")) return 0;
  if (!lego) lego = load(specs[0]);

  // Knobs on lego, each for the same training time.
  struct Knob {
    std::string name;
    std::function<void(train::DensityTrainConfig&)> apply;
  };
  const std::vector<Knob> knobs = {
      {"baseline (step 0.5 voxel, 300^3, rank 16/48, mask on)", [](train::DensityTrainConfig&) {}},
      {"step 1.0 voxel (half the samples)", [](train::DensityTrainConfig& c) { c.model.step_ratio = 1.0f; }},
      {"step 0.25 voxel (twice the samples)", [](train::DensityTrainConfig& c) { c.model.step_ratio = 0.25f; }},
      {"final grid 150^3", [](train::DensityTrainConfig& c) { c.schedule.voxels_final = 150LL * 150 * 150; }},
      {"rank halved (8/24)",
       [](train::DensityTrainConfig& c) {
         c.model.density_rank = {8, 8, 8};
         c.model.app_rank = {24, 24, 24};
       }},
      {"alpha mask off", [](train::DensityTrainConfig& c) { c.alpha_mask = false; }},
  };
  std::cout << "\nknobs on lego 1/4, " << knob_budget << " s of training each:\n";
  json kt = json::array();
  std::vector<std::tuple<std::string, double, double, double>> rows;
  for (const auto& k : knobs) {
    auto cfg = train::default_density_config(*lego);
    k.apply(cfg);
    const auto r = timed_run(*lego, cfg, knob_budget, eval_views, 1, k.name);
    kt.push_back({{"knob", k.name},
                  {"s_per_iteration", r.s_per_it},
                  {"samples_per_ray", r.samples_per_ray},
                  {"iterations", r.iterations},
                  {"psnr", r.final_psnr}});
    rows.emplace_back(k.name, r.s_per_it, r.samples_per_ray, r.final_psnr);
    doc["knobs"] = kt;
    save();
  }
  const double base_spi = std::get<1>(rows.front()), base_psnr = std::get<3>(rows.front());
  std::cout << "\n" << std::left << std::setw(56) << "knob" << std::right << std::setw(10) << "s/it" << std::setw(12)
            << "time/it" << std::setw(14) << "samples/ray" << std::setw(10) << "PSNR" << std::setw(10) << "dPSNR\n";
  for (const auto& [name, spi, spr, p] : rows)
    std::cout << std::left << std::setw(56) << name << std::right << std::fixed << std::setprecision(3)
              << std::setw(10) << spi << std::setprecision(2) << std::setw(11) << spi / base_spi << "x"
              << std::setprecision(1) << std::setw(14) << spr << std::setprecision(2) << std::setw(10) << p
              << std::showpos << std::setw(10) << p - base_psnr << std::noshowpos << "\n";
  return 0;
}

}  // namespace stylerf::bench
