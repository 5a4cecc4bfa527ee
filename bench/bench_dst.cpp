// `stylerf bench dst --size 256 [--ckpt CKPT] [--repeats N] [--json F]`: the deferred style transformation
// against the per-point one (StyleRF Sec. 3.3), on one size x size patch (one ray per pixel, in chunks of
// 4096 rays, the same for both):
//   DST stage: from the kept samples' SICT outputs [K, 32] to the styled map [R, 256]:
//     per point: DST on every sample ([K, 32] -> [K, 256]), then composite 256 channels;
//     deferred:  composite 32 channels ([K, 32] -> [R, 32]), then DST on the map;
//   whole render: march, density, SICT and the DST stage, both ways.
// Prints seconds (best of --repeats after a warm-up), peak device memory held by the stage (the runtime's
// live-tensor high-water mark above what existed before it), their ratios, the DST stage's GFLOP/s, and
// how closely the two maps agree (max |difference| / max |value|).
#include <chrono>
#include <functional>
#include <cmath>
#include <iomanip>
#include <iostream>
#include <nlohmann/json.hpp>

#include "bench/bench.hpp"
#include "bench/bench_setup.hpp"
#include "bench/random_fill.hpp"
#include "host/error.hpp"
#include "host/files.hpp"
#include "host/runtime.hpp"
#include "lib/io/checkpoint.hpp"
#include "lib/model/style_model.hpp"

namespace stylerf::bench {

using host::Error;
using host::Tensor;

namespace {

double now_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

model::StyleModel style_model_for(const BenchOptions& opt, const Setup& st) {
  if (!opt.ckpt.empty()) {
    const auto ck = io::load_checkpoint(opt.ckpt, "");
    if (ck.kind == "style") return model::StyleModel::load(ck);
    if (ck.kind == "features")
      return model::StyleModel::create(model::FeatureModel::load(ck), style::SictMode::VolumeAdaptive, true, 1);
  }
  model::FeatureFieldConfig fc;
  fc.rank = st.rank;
  // The decoder plays no part here: the paper profile's needs no weight file.
  return model::StyleModel::create(model::FeatureModel::create(st.geo, fc, model::DecoderProfile::Paper, 1),
                                   style::SictMode::VolumeAdaptive, true, 1);
}

struct Measure {
  double seconds = 1e300;
  size_t peak = 0;
};

}  // namespace

int bench_dst(const BenchOptions& opt) {
  auto& rt = host::Runtime::instance();
  if (opt.size < 8 || opt.size % 8) throw Error("bench dst: --size must be a positive multiple of 8");
  const int S = opt.quick ? 64 : opt.size, repeats = opt.quick ? 1 : opt.repeats;
  BenchOptions o = opt;
  o.size = S;
  const Setup st = setup_from(o);
  const model::StyleModel sm = style_model_for(opt, st);
  // A style's code from relu3_1-like rows (the 64 x 64 positions of a 256 x 256 style image); the DST
  // stage's cost does not depend on their values.
  const std::vector<float> rows = uniform_floats(size_t(4096) * 256, 1, 0.0f, 3.0f);
  const style::StyleCode code = sm.dst.style_code(Tensor::from_host(rows, {4096, 256}, "style rows"), nullptr);
  int w = 0, h = 0;
  const scene::Rays rays = model::block_rays(st.scene, st.cam, 1, w, h);
  const int64_t R = int64_t(w) * h, chunk = 4096;
  std::vector<Tensor> origins, dirs;
  for (int64_t b = 0; b < R; b += chunk) {
    const int64_t n = std::min(chunk, R - b);
    origins.push_back(Tensor::from_host(std::vector<float>(rays.origins.begin() + 3 * b, rays.origins.begin() + 3 * (b + n)), {n, 3}));
    dirs.push_back(Tensor::from_host(std::vector<float>(rays.directions.begin() + 3 * b, rays.directions.begin() + 3 * (b + n)), {n, 3}));
  }
  std::cout << "device: " << rt.device().describe() << "\n"
            << "DST: deferred (on the rendered map) vs per point, " << S << "x" << S << " rays in chunks of " << chunk
            << "\n  geometry: " << st.source << "\n  best of " << repeats << " after a warm-up\n";

  // The kept samples' SICT outputs of every chunk (the DST stage's common input), kept outside the timing.
  std::vector<model::StyleModel::Context> ctxs(origins.size());
  int64_t kept = 0;
  for (size_t i = 0; i < origins.size(); ++i) {
    sm.render_content(origins[i], dirs[i], false, 0, &ctxs[i]);
    kept += ctxs[i].rays.kept_layout.count;
  }
  auto time_it = [&](const std::function<void(std::vector<Tensor>*)>& f, std::vector<Tensor>* out) {
    Measure m;
    for (int rep = 0; rep <= repeats; ++rep) {
      out->clear();
      rt.finish();
      rt.reset_peak();
      const size_t base = rt.live_bytes();
      const double t0 = now_s();
      f(out);
      rt.finish();
      const double t = now_s() - t0;
      if (rep == 0) continue;
      m.seconds = std::min(m.seconds, t);
      m.peak = std::max(m.peak, rt.peak_live_bytes() - base);
    }
    return m;
  };
  // The stage's own memory: each chunk's output is downloaded and dropped (as a renderer would), so the
  // peak is one chunk's working set.
  std::vector<Tensor> pp_out, def_out;
  std::vector<std::vector<float>> pp_host, def_host;
  const Measure pp = time_it(
      [&](std::vector<Tensor>* out) {
        for (auto& c : ctxs) {
          if (c.rays.kept_layout.count == 0) continue;
          const Tensor y = sm.dst.apply_per_point(c.rays.kept_values, code);
          out->clear();  // only the newest chunk's map stays alive
          out->push_back(render::composite_values_forward(c.rays.kept_layout, c.rays.kept_w, y).value);
        }
      },
      &pp_out);
  const Measure def = time_it(
      [&](std::vector<Tensor>* out) {
        for (auto& c : ctxs) {
          if (c.rays.kept_layout.count == 0) continue;
          const auto comp = render::composite_values_forward(c.rays.kept_layout, c.rays.kept_w, c.rays.kept_values);
          out->clear();
          out->push_back(sm.dst.apply(comp.value, comp.acc, code, nullptr));
        }
      },
      &def_out);
  // Agreement on the last chunk (both orders from the same kept samples).
  double err = 0, scale = 0;
  {
    const auto a = pp_out.back().to_host(), b = def_out.back().to_host();
    for (size_t i = 0; i < a.size(); ++i) {
      err = std::max(err, double(std::abs(a[i] - b[i])));
      scale = std::max(scale, double(std::abs(a[i])));
    }
  }
  // Whole renders, both ways (march, density, SICT included).
  std::vector<Tensor> sink;
  const Measure pp_all = time_it(
      [&](std::vector<Tensor>*) {
        for (size_t i = 0; i < origins.size(); ++i) sm.render_styled_per_point(origins[i], dirs[i], code);
      },
      &sink);
  const Measure def_all = time_it(
      [&](std::vector<Tensor>*) {
        for (size_t i = 0; i < origins.size(); ++i) {
          const auto c = sm.render_content(origins[i], dirs[i], false, 0, nullptr);
          sm.dst.apply(c.c, c.kept_acc, code, nullptr);
        }
      },
      &sink);
  // DST FLOPs: per point 2 * 32 * 256 per sample (+ 2 * 256 composite); deferred 2 * 32 per sample
  // composite + 2 * 32 * 256 per ray.
  const double flops_pp = double(kept) * (2.0 * 32 * 256 + 2.0 * 256), flops_def = double(kept) * 2.0 * 32 + double(R) * 2.0 * 32 * 256;
  const double MiB = 1048576.0;
  std::cout << std::fixed << "  " << R << " rays, " << kept << " kept samples (" << std::setprecision(1)
            << double(kept) / double(R) << " per ray)\n"
            << std::left << std::setw(28) << "" << std::right << std::setw(12) << "per point" << std::setw(12)
            << "deferred" << std::setw(10) << "ratio\n"
            << std::setprecision(4) << std::left << std::setw(28) << "DST stage: time (s)" << std::right
            << std::setw(12) << pp.seconds << std::setw(12) << def.seconds << std::setw(9) << std::setprecision(1)
            << pp.seconds / def.seconds << "x\n"
            << std::left << std::setw(28) << "DST stage: peak (MiB)" << std::right << std::setw(12) << pp.peak / MiB
            << std::setw(12) << def.peak / MiB << std::setw(9) << double(pp.peak) / double(std::max<size_t>(def.peak, 1))
            << "x\n"
            << std::left << std::setw(28) << "DST stage: GFLOP/s" << std::right << std::setw(12)
            << flops_pp / pp.seconds / 1e9 << std::setw(12) << flops_def / def.seconds / 1e9 << "\n"
            << std::setprecision(3) << std::left << std::setw(28) << "whole render: time (s)" << std::right
            << std::setw(12) << pp_all.seconds << std::setw(12) << def_all.seconds << std::setw(9)
            << std::setprecision(1) << pp_all.seconds / def_all.seconds << "x\n"
            << std::left << std::setw(28) << "whole render: peak (MiB)" << std::right << std::setw(12)
            << pp_all.peak / MiB << std::setw(12) << def_all.peak / MiB << std::setw(9)
            << double(pp_all.peak) / double(std::max<size_t>(def_all.peak, 1)) << "x\n"
            << std::scientific << std::setprecision(2) << "  the two maps agree to " << (scale > 0 ? err / scale : err)
            << " of their largest value (goal: DST >= 10x less memory, >= 5x less time)" << std::endl;
  if (!opt.json_path.empty()) {
    nlohmann::json j = {{"bench", "dst"},          {"size", S},
                        {"rays", R},               {"kept", kept},
                        {"source", st.source},     {"dst_per_point_s", pp.seconds},
                        {"dst_deferred_s", def.seconds}, {"dst_per_point_peak_bytes", pp.peak},
                        {"dst_deferred_peak_bytes", def.peak}, {"render_per_point_s", pp_all.seconds},
                        {"render_deferred_s", def_all.seconds}, {"render_per_point_peak_bytes", pp_all.peak},
                        {"render_deferred_peak_bytes", def_all.peak}, {"relative_difference", scale > 0 ? err / scale : err}};
    host::write_file_atomic(opt.json_path, j.dump(1) + "\n");
  }
  return 0;
}

}  // namespace stylerf::bench
