// `stylerf bench patch --stage 3 --profile fast|paper --size 256 [--ckpt CKPT] [--json F]`: one style step
// (StyleRF stage 3) at size x size pixels, part by part, each timed with the queue drained (best of
// --repeats after a warm-up step):
// --style-decoder vgg-adain times VGG's frozen relu3_1 -> relu4_1 and AdaIN's decoder as the decoder.
//   forward:  render (march, density, weights, keep, compositing of the 32 SICT channels), field (grid
//             components per kept sample), SICT (on the components, the basis folded in), DST (style code
//             + apply), decoder, VGG (style image, true patch, stylised patch; to relu4_1);
//   backward: VGG (to the input), decoder, DST (apply + style branch), composite, SICT, optimiser.
// GFLOP/s for the GEMM-bound parts (convs; SICT's q/k/v and attention; DST's products).
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
#include "lib/model/map_decoder.hpp"
#include "lib/model/style_model.hpp"
#include "lib/nn/adam.hpp"
#include "lib/nn/layout.hpp"
#include "lib/nn/linear.hpp"
#include "lib/train/style_losses.hpp"

namespace stylerf::bench {

using host::Error;
using host::Tensor;

namespace {

double now_ms() {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// SictHead's work with the queue drained between the field lookup and SICT, to time them apart.
class TimedSictHead : public model::SampleHead {
 public:
  TimedSictHead(const model::FeatureField& f, style::Sict& s, bool with_components)
      : field_(f), sict_(s), with_components_(with_components) {}
  int channels() const override {
    return style::Sict::kEmbed + (with_components_ ? int(field_.basis.value.dim(0)) : 0);
  }
  Tensor forward(const Tensor& pos, const Tensor& dirs, std::unique_ptr<Context>* ctx) const override {
    auto& rt = host::Runtime::instance();
    rt.finish();
    const double t0 = now_ms();
    const Tensor comps = field_.head.forward(pos, dirs, nullptr);
    rt.finish();
    const double t1 = now_ms();
    auto c = std::make_unique<model::SictHead::SictContext>();
    Tensor y = sict_.forward_factored(comps, field_.basis.value, true, &c->sict);
    rt.finish();
    field_ms = t1 - t0;
    sict_ms = now_ms() - t1;
    points = comps.dim(0);
    *ctx = std::move(c);
    return with_components_ ? nn::concat_columns(y, comps) : y;
  }
  void backward(const Context& ctx, const Tensor& dvalues) override {
    auto& rt = host::Runtime::instance();
    rt.finish();
    const double t0 = now_ms();
    const Tensor dc = with_components_ ? nn::take_columns(dvalues, 0, style::Sict::kEmbed) : dvalues;
    sict_.backward(dynamic_cast<const model::SictHead::SictContext&>(ctx).sict, dc, false);
    rt.finish();
    sict_bwd_ms = now_ms() - t0;
  }
  void collect_params(std::vector<nn::Param*>& out) override { sict_.collect_params(out); }
  mutable double field_ms = 0, sict_ms = 0, sict_bwd_ms = 0;
  mutable int64_t points = 0;

 private:
  const model::FeatureField& field_;
  style::Sict& sict_;
  bool with_components_;
};

}  // namespace

int bench_patch_style(const BenchOptions& opt) {
  auto& rt = host::Runtime::instance();
  if (opt.size < 8 || opt.size % 8) throw Error("bench patch: --size must be a positive multiple of 8");
  const auto profile = model::parse_decoder_profile(opt.profile);
  const auto decoder_kind = model::parse_style_decoder(opt.style_decoder);
  const int S = opt.quick ? 64 : opt.size, repeats = opt.quick ? 1 : opt.repeats;
  BenchOptions o = opt;
  o.size = S;
  const Setup st = setup_from(o);
  model::FeatureFieldConfig fc;
  fc.rank = st.rank;
  model::StyleModel m = model::StyleModel::create(model::FeatureModel::create(st.geo, fc, profile, 1),
                                                  style::SictMode::VolumeAdaptive, true, 1, decoder_kind,
                                                  opt.content_skip);
  const bool vgg_adain = decoder_kind != model::StyleDecoderKind::Stage2;
  if (opt.decoder_phases && !model::map_decoder_for(decoder_kind).has_vgg_pool())
    throw Error("bench patch: --decoder-phases needs --style-decoder vgg-adain or vgg-adain-relu4");
  m.decoder_phases = opt.decoder_phases;
  nn::VggEncoder vgg = nn::VggEncoder::load_default();
  nn::Adam adam({{"stylizer", 1e-4f}, {"decoder", 1e-5f}}, 0.9f, 0.99f);
  int w = 0, h = 0;
  const scene::Rays rays = model::block_rays(st.scene, st.cam, m.stride(), w, h);
  const int64_t R = int64_t(w) * h;
  const Tensor o_t = Tensor::from_host(rays.origins, {R, 3}, "patch origins");
  const Tensor d_t = Tensor::from_host(rays.directions, {R, 3}, "patch directions");
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::vector<float> gtv(size_t(3) * S * S), sv(size_t(3) * 256 * 256);
  for (auto& x : gtv) x = u(rng);
  for (auto& x : sv) x = u(rng);
  const Tensor gt = Tensor::from_host(gtv, {1, 3, S, S}, "bench target patch");
  const Tensor style_img = Tensor::from_host(sv, {1, 3, 256, 256}, "bench style image");
  std::cout << "device: " << rt.device().describe() << "\n"
            << "stage-3 style step, " << model::decoder_profile_name(profile) << " profile, " << S << "x" << S
            << " pixels: " << R << " rays (" << w << "x" << h << " map), style image 256x256"
            << (m.content_skip ? ", content skip" : "") << ", decoder "
            << (vgg_adain ? std::string(model::style_decoder_name(decoder_kind)) + (m.decoder_phases ? ", pool at 4 phases: " : ": ") +
                                "VGG conv3_2..conv4_1 (frozen), then " + m.style_decoder.spec().describe()
                          : m.features.decoder.spec().describe()) << "\n  geometry: " << st.source << "\n  best of " << repeats
            << " after a warm-up step\n";
  const char* names[] = {"render fwd", "field fwd",  "SICT fwd",     "DST fwd",      "decoder fwd", "VGG fwd",
                         "VGG bwd",    "decoder bwd", "DST bwd",      "composite bwd", "SICT bwd",    "optimizer"};
  constexpr int kParts = 12;
  std::vector<double> best(kParts, 1e300);
  double best_total = 1e300;
  int64_t samples = 0, kept = 0;
  for (int rep = 0; rep <= repeats; ++rep) {
    double p[kParts] = {};
    auto lap = [&](double& t) {
      rt.finish();
      const double n = now_ms();
      const double d = n - t;
      t = n;
      return d;
    };
    m.zero_grad();
    rt.finish();
    rt.reset_timings();  // under STYLERF_PROFILE=1: print_top_kernels shows the last step
    const double start = now_ms();
    double t = start;
    TimedSictHead head(m.features.field, m.sict, m.content_skip);
    model::RayContext rctx;
    model::RayOptions ro;
    ro.jitter = true;
    ro.seed = uint32_t(rep);
    const model::RayResult r = model::render_rays(m.features.geo, head, o_t, d_t, ro, &rctx);
    p[0] = lap(t) - head.field_ms - head.sict_ms;
    p[1] = head.field_ms;
    p[2] = head.sict_ms;
    const nn::VggFeatures st_taps = vgg.forward(style_img, 4, false);
    const double vgg_style_ms = lap(t);
    style::Dst::StyleContext sctx;
    const style::StyleCode code = m.style_code(st_taps, &sctx);
    model::StyleModel::Context mctx;  // its DST and content-skip parts
    Tensor y = m.transform(r.value, r.kept_acc, code, &mctx);
    p[3] = lap(t);
    model::StyleModel::DecoderCtx dctx;
    const Tensor rgb = m.decode_map(nn::rows_to_image(y, h, w), &code, &dctx);
    p[4] = lap(t);
    const nn::VggFeatures ft = vgg.forward(gt, 4, false);
    const nn::VggFeatures fo = vgg.forward(rgb, 4, true);
    nn::VggFeatures g;
    train::style_losses(fo, ft[3], st_taps, nullptr, {}, &g);
    p[5] = lap(t) + vgg_style_ms;
    const Tensor drgb = vgg.backward(g);
    vgg.release();
    p[6] = lap(t);
    const Tensor dmap = m.decode_map_backward(dctx, drgb, true);
    p[7] = lap(t);
    const auto ag = m.transform_backward(mctx, nn::rows_to_image_backward(dmap));
    m.dst.style_code_backward(sctx, ag.dT, ag.dmean, ag.dstd, false);
    p[8] = lap(t);
    const Tensor dvalues = m.content_skip ? nn::take_columns_backward(ag.dc, 0, m.content_channels()) : ag.dc;
    model::render_rays_backward(m.features.geo, head, rctx, dvalues, Tensor(), nullptr);
    p[9] = lap(t) - head.sict_bwd_ms;
    p[10] = head.sict_bwd_ms;
    adam.step(m.params(), 1.0f);
    p[11] = lap(t);
    samples = r.samples;
    kept = r.kept;
    if (rep == 0) continue;  // warm-up: kernel compiles
    for (int i = 0; i < kParts; ++i) best[i] = std::min(best[i], p[i]);
    best_total = std::min(best_total, t - start);
  }
  // vgg-adain: the tail's convs at the map's size (three 256 -> 256) and half of it (conv4_1), then AdaIN's
  // decoder from half the map's size; the frozen tail's backward computes d input only (1x its forward,
  // against 2x for a trained stack). With the pool's four phases, conv4_1 and the decoder's first conv
  // run four times.
  const double phases = m.decoder_phases ? 4.0 : 1.0;
  const double first = 2.0 * 9.0 * 512 * 256 * (h / 2) * (w / 2);
  const double tail = vgg_adain ? 2.0 * 9.0 * (3.0 * 256 * 256 * h * w + phases * 256.0 * 512 * (h / 2) * (w / 2)) : 0.0;
  const double stack = vgg_adain ? stack_flops(m.style_decoder, h / 2, w / 2) + (phases - 1) * first
                                 : stack_flops(m.features.decoder, h, w);
  const double dec = tail + stack, dec_bwd = tail + 2 * stack;
  const double vg = 2 * vgg_flops(S) + vgg_flops(256);  // true + stylised patch, the style image
  // SICT per point, on the F grid components (Sict::forward_factored): the covariance 2 F^2, q/k/v 2 F 96,
  // attention ~ 4 * 32 * 32 (logits and weighted sum); backward: f^T dqkv 2 F 96 and the attention's ~3x.
  const double F = fc.rank[0] + fc.rank[1] + fc.rank[2];
  const double sict = double(kept) * (2.0 * F * F + 2.0 * F * 96 + 4.0 * 32 * 32);
  const double sict_bwd = double(kept) * (2.0 * F * 96 + 12.0 * 32 * 32);
  const double L = 64.0 * 64.0;  // relu3_1 positions of the 256 x 256 style
  const double dst = L * 2.0 * (256 * 128 + 128 * 64 + 64 * 32) + L * 2.0 * 32 * 32 + 2.0 * 1024 * 1024 +
                     double(R) * 2.0 * (32 * 256 + 256);
  const double flops[kParts] = {0, 0, sict, dst, dec, vg, vgg_flops(S), dec_bwd, 2 * dst, 0, sict_bwd, 0};
  nlohmann::json rows = nlohmann::json::array();
  std::cout << std::left << std::setw(14) << "part" << std::right << std::setw(10) << "s" << std::setw(12) << "GFLOP"
            << std::setw(12) << "GFLOP/s" << "\n";
  double total_flops = 0;
  for (int i = 0; i < kParts; ++i) {
    const double s = best[i] / 1e3;
    total_flops += flops[i];
    std::cout << std::left << std::setw(14) << names[i] << std::right << std::fixed << std::setprecision(3)
              << std::setw(10) << s << std::setprecision(1) << std::setw(12) << flops[i] / 1e9 << std::setw(12)
              << (flops[i] > 0 && s > 0 ? flops[i] / 1e9 / s : 0.0) << "\n";
    rows.push_back({{"part", names[i]}, {"seconds", s}, {"gflop", flops[i] / 1e9},
                    {"gflop_s", flops[i] > 0 && s > 0 ? flops[i] / 1e9 / s : 0.0}});
  }
  std::cout << std::left << std::setw(14) << "step" << std::right << std::setprecision(3) << std::setw(10)
            << best_total / 1e3 << std::setprecision(1) << std::setw(12) << total_flops / 1e9 << "\n"
            << "samples " << samples << " (" << std::setprecision(1) << double(samples) / double(R) << " per ray), kept "
            << kept << " (SICT points)\n";
  const std::string top = print_top_kernels(25);
  if (!opt.json_path.empty()) {
    nlohmann::json j = {{"bench", "patch"}, {"stage", 3}, {"profile", model::decoder_profile_name(profile)},
                        {"style_decoder", model::style_decoder_name(decoder_kind)},
                        {"decoder_phases", m.decoder_phases},
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
