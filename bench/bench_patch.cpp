// `stylerf bench patch --stage 2 --profile fast|paper --size 256 [--ckpt CKPT] [--json F]`: one stage-2
// patch step at size x size pixels, part by part, each timed with the queue drained (best of --repeats
// after a warm-up step):
//   render fwd (march, density, weights, feature grid, composite, basis), decoder fwd, VGG fwd (the true
//   patch and the decoded one, to relu4_1), VGG bwd (to the input), decoder bwd (dX, dW), render bwd
//   (composite, feature grid scatter, basis), optimiser (Adam over every parameter).
// Conv parts report GFLOP/s (2 * Cin * Cout * 9 * H * W per conv forward; backward: dX and dW for the
// decoder, dX only for the frozen VGG); render parts report samples/s.
// The geometry is a checkpoint's (--ckpt, density or feature kind; the view is its first training camera
// resized to size x size, so any scene gives the asked patch size), or, without --ckpt, a synthetic
// positive density over a 3-unit box where every sample is kept (a worst case for the render parts).
#include <chrono>
#include <cmath>
#include <iomanip>
#include <iostream>
#include <nlohmann/json.hpp>
#include <random>

#include "bench/timing.hpp"
#include "bench/bench.hpp"
#include "bench/bench_setup.hpp"
#include "host/error.hpp"
#include "host/files.hpp"
#include "host/runtime.hpp"
#include "lib/io/checkpoint.hpp"
#include "lib/model/density_model.hpp"
#include "lib/model/feature_model.hpp"
#include "lib/nn/adam.hpp"
#include "lib/nn/layout.hpp"
#include "lib/nn/ops.hpp"
#include "lib/nn/vgg.hpp"
#include "lib/scene/scene_meta.hpp"

namespace stylerf::bench {

using host::Error;
using host::Tensor;

namespace {

double now_ms() {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

}  // namespace

int bench_patch(const BenchOptions& opt) {
  auto& rt = host::Runtime::instance();
  if (opt.stage == 3) return bench_patch_style(opt);
  if (opt.stage != 2) throw Error("bench patch: --stage must be 2 or 3, got " + std::to_string(opt.stage));
  if (opt.size < 8 || opt.size % 8) throw Error("bench patch: --size must be a positive multiple of 8");
  const auto profile = model::parse_decoder_profile(opt.profile);
  const int S = opt.quick ? 64 : opt.size, repeats = opt.quick ? 1 : opt.repeats;
  BenchOptions o = opt;
  o.size = S;
  Setup st = setup_from(o);
  model::FeatureFieldConfig fc;
  fc.rank = st.rank;
  auto m = model::FeatureModel::create(st.geo, fc, profile, 1);
  nn::VggEncoder vgg = nn::VggEncoder::load_default();
  nn::Adam adam({{"grid", 0.02f}, {"basis", 1e-2f}, {"decoder", 1e-4f}}, 0.9f, 0.99f);
  int w = 0, h = 0;
  const scene::Rays rays = model::block_rays(st.scene, st.cam, m.stride(), w, h);
  const int64_t R = int64_t(w) * h;
  const Tensor o_t = Tensor::from_host(rays.origins, {R, 3}, "patch origins");
  const Tensor d_t = Tensor::from_host(rays.directions, {R, 3}, "patch directions");
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::vector<float> gtv(size_t(3) * S * S);
  for (auto& x : gtv) x = u(rng);
  const Tensor gt = Tensor::from_host(gtv, {1, 3, S, S}, "bench target patch");

  std::cout << "device: " << rt.device().describe() << "\n"
            << "stage-2 patch step, " << model::decoder_profile_name(profile) << " profile, " << S << "x" << S
            << " pixels: " << R << " rays (" << w << "x" << h << " feature map), decoder "
            << m.decoder.spec().describe() << "\n  geometry: " << st.source << "\n  best of " << repeats
            << " after a warm-up step\n";

  const char* names[] = {"render fwd", "decoder fwd", "VGG fwd", "VGG bwd", "decoder bwd", "render bwd", "optimizer"};
  constexpr int kParts = 7;
  std::vector<double> best(kParts, 1e300);
  double best_total = 1e300;
  int64_t samples = 0, kept = 0;
  for (int rep = 0; rep <= repeats; ++rep) {
    double t[kParts + 1];
    rt.finish();
    rt.reset_timings();  // under STYLERF_PROFILE=1: print_top_kernels shows the last step
    t[0] = now_ms();
    m.zero_grad();
    model::FeatureField::Context fctx;
    model::RayOptions ro;
    ro.jitter = true;
    ro.seed = uint32_t(rep);
    const model::RayResult r = m.field.render(m.geo, o_t, d_t, ro, &fctx);
    Tensor map = nn::rows_to_image(r.value, h, w);
    rt.finish();
    t[1] = now_ms();
    nn::ConvStack::Ctx dctx;
    Tensor rgb = m.decoder.forward(map, &dctx);
    rt.finish();
    t[2] = now_ms();
    const nn::VggFeatures ft = vgg.forward(gt, 4, false);
    const nn::VggFeatures fo = vgg.forward(rgb, 4, true);
    nn::VggFeatures g;
    g[2] = nn::mse_backward(fo[2], ft[2], 0.1f);
    g[3] = nn::mse_backward(fo[3], ft[3], 0.1f);
    rt.finish();
    t[3] = now_ms();
    Tensor drgb = vgg.backward(g);
    vgg.release();
    nn::axpby(1.0f, nn::mse_backward(rgb, gt, 1.0f), 1.0f, drgb);
    rt.finish();
    t[4] = now_ms();
    Tensor dmap = m.decoder.backward(dctx, drgb, true);
    rt.finish();
    t[5] = now_ms();
    m.field.render_backward(m.geo, fctx, nn::rows_to_image_backward(dmap), Tensor());
    rt.finish();
    t[6] = now_ms();
    adam.step(m.params(), 1.0f);
    rt.finish();
    t[7] = now_ms();
    samples = r.samples;
    kept = r.kept;
    if (rep == 0) continue;  // warm-up: kernel compiles
    for (int i = 0; i < kParts; ++i) best[i] = std::min(best[i], t[i + 1] - t[i]);
    best_total = std::min(best_total, t[kParts] - t[0]);
  }
  const double dec = stack_flops(m.decoder, h, w), vg = vgg_flops(S);
  const double flops[kParts] = {0, dec, 2 * vg, vg, 2 * dec, 0, 0};
  nlohmann::json rows = nlohmann::json::array();
  std::cout << std::left << std::setw(14) << "part" << std::right << std::setw(10) << "s" << std::setw(12)
            << "GFLOP" << std::setw(12) << "GFLOP/s" << std::setw(16) << "Msamples/s" << "\n";
  double total_flops = 0;
  for (int i = 0; i < kParts; ++i) {
    const double s = best[i] / 1e3;
    total_flops += flops[i];
    std::cout << std::left << std::setw(14) << names[i] << std::right << std::fixed << std::setprecision(3)
              << std::setw(10) << s << std::setprecision(1) << std::setw(12) << flops[i] / 1e9 << std::setw(12)
              << (flops[i] > 0 ? flops[i] / 1e9 / s : 0.0) << std::setw(16)
              << ((i == 0 || i == 5) ? double(samples) / 1e6 / s : 0.0) << "\n";
    rows.push_back({{"part", names[i]}, {"seconds", s}, {"gflop", flops[i] / 1e9},
                    {"gflop_s", flops[i] > 0 ? flops[i] / 1e9 / s : 0.0}});
  }
  std::cout << std::left << std::setw(14) << "step" << std::right << std::setprecision(3) << std::setw(10)
            << best_total / 1e3 << std::setprecision(1) << std::setw(12) << total_flops / 1e9 << "\n"
            << "samples " << samples << " (" << std::setprecision(1) << double(samples) / double(R) << " per ray), kept "
            << kept << "\n";
  const std::string top = print_top_kernels(25);
  if (!opt.json_path.empty()) {
    nlohmann::json j = {{"bench", "patch"}, {"stage", 2}, {"profile", model::decoder_profile_name(profile)},
                        {"size", S}, {"rays", R}, {"samples", samples}, {"kept", kept},
                        {"geometry", st.source}, {"device", rt.device().describe()}, {"repeats", repeats},
                        {"step_seconds", best_total / 1e3}, {"parts", rows}};
    if (!top.empty()) j["kernels"] = nlohmann::json::parse(top);
    host::write_file_atomic(opt.json_path, j.dump(2) + "\n");
    std::cout << "wrote " << opt.json_path << "\n";
  }
  return 0;
}

}  // namespace stylerf::bench
