// Perf mode of the style-stage kernels, part of `stylerf bench ops`, at the sizes a 256x256 fast-profile
// style step runs them (64x64 rays, ~32 kept samples a ray on lego: K = 131072 points; --quick: 8192):
//   - SICT: column statistics of [K, 256] (GB/s), the point norm forward / backward (GB/s), the channel
//     attention forward / backward (GFLOP/s: 4 * 32 * 32 multiply-adds per point forward, ~3x that
//     backward, plus 1024 exponentials counted as one FLOP each);
//   - DST: the style code of a 256x256 style's relu3_1 (L = 4096 positions) forward / backward and its
//     application to 64x64 rays forward / backward (GFLOP/s from the GEMM shapes);
//   - the region indicator of zero-shot composition (kernels/region.cl; GB/s).
#include <algorithm>
#include <cstdio>

#include "bench/bench_ops_parts.hpp"
#include "bench/timing.hpp"
#include "lib/model/region.hpp"
#include "lib/nn/columns.hpp"
#include "lib/nn/layout.hpp"
#include "lib/style/content_skip.hpp"
#include "lib/style/dst.hpp"
#include "lib/nn/reduce_path.hpp"
#include "lib/style/sict.hpp"

namespace stylerf::bench {
namespace {

using host::Tensor;

void row(const char* op, const char* shape, const Timing& t, double flops, double bytes) {
  std::printf("  %-26s %-18s %9.3f %9.2f %8.2f\n", op, shape, t.wall_ms, flops > 0 ? flops / (t.wall_ms * 1e6) : 0.0,
              bytes > 0 ? bytes / (t.wall_ms * 1e6) : 0.0);
  std::fflush(stdout);
}

}  // namespace

void bench_ops_style(const BenchOptions& opt) {
  const int K = opt.quick ? 8192 : 131072, C = 256, E = 32, L = 4096, R = 4096;
  const int reps = opt.quick ? 1 : std::max(opt.repeats, 3);
  std::printf("style-stage kernels (kernels/sict.cl, dst.cl, columns.cl, layout.cl copy_columns), best of %d wall times\n", reps);
  std::printf("  %-26s %-18s %9s %9s %8s\n", "op", "shape", "ms", "GFLOP/s", "GB/s");
  const Tensor x = Tensor::full({K, C}, 0.5f), dy256 = Tensor::full({K, C}, 0.1f);
  const Tensor mean = Tensor::full({C}, 0.1f), var = Tensor::full({C}, 2.0f);
  const double kc = 4.0 * double(K) * C;
  row("column mean", "[K,256]", best_of(reps, [&] { nn::column_mean(x); }), 0, kc);
  row("column variance", "[K,256]", best_of(reps, [&] { nn::column_variance(x, mean, 0); }), 0, kc);
  row("point norm fwd", "[K,256]", best_of(reps, [&] { style::point_norm_forward(x, mean, var, 1e-5f); }), 0, 2 * kc);
  row("point norm bwd (batch)", "[K,256]",
      best_of(reps, [&] { style::point_norm_backward(x, var, dy256, 1e-5f, false); }), 0, 5 * kc);
  const Tensor qkv = Tensor::full({K, 3 * E}, 0.3f), dout = Tensor::full({K, E}, 0.2f);
  const double att = double(K) * (4.0 * E * E + E * E);
  for (auto path : {nn::ReductionPath::PerItem, nn::ReductionPath::WorkGroup}) {  // kernels/sict.cl 3 and 3b
    const auto old = nn::set_reduction_path(path);
    const std::string tag = path == nn::ReductionPath::PerItem ? " (per-item)" : " (work-group)";
    row(("channel attention fwd" + tag).c_str(), "[K,96]->[K,32]",
        best_of(reps, [&] { style::channel_attention_forward(qkv); }), att, 0);
    row(("channel attention bwd" + tag).c_str(), "[K,32]->[K,96]",
        best_of(reps, [&] { style::channel_attention_backward(qkv, dout); }), 3 * att, 0);
    nn::set_reduction_path(old);
  }
  style::Dst d = style::Dst::create(true, 0, 1);
  const Tensor s = Tensor::full({L, C}, 0.7f);
  style::Dst::StyleContext sctx;
  const double code_flops = double(L) * 2.0 * (C * 128 + 128 * 64 + 64 * E) + double(L) * 2.0 * E * E + 2.0 * 1024 * 1024;
  style::StyleCode code;
  row("DST style code fwd", "[4096,256]", best_of(reps, [&] { code = d.style_code(s, &sctx); }), code_flops, 0);
  const Tensor dT = Tensor::full({E, E}, 0.01f), dm = Tensor::full({C}, 0.01f);
  row("DST style code bwd", "[4096,256]",
      best_of(reps, [&] { d.style_code_backward(sctx, dT, dm, dm, true); }), 2 * code_flops, 0);
  const Tensor c = Tensor::full({R, E}, 0.2f), acc = Tensor::full({R}, 0.9f), dy = Tensor::full({R, C}, 0.1f);
  style::Dst::ApplyContext actx;
  const double apply_flops = double(R) * 2.0 * (E * C + C);
  row("DST apply fwd", "[4096,32]->256", best_of(reps, [&] { d.apply(c, acc, code, &actx); }), apply_flops, 0);
  row("DST apply bwd", "[4096,256]", best_of(reps, [&] { d.apply_backward(actx, dy, true); }), 2 * apply_flops, 0);
  // The content skip on a training patch's rays: the field's 144 components beside SICT's 32 columns (3D maps)
  // and a 2D map's 256 features (no basis); and the column copies that carry the components.
  style::ContentSkip skip = style::ContentSkip::create(0);
  const int F = 144;
  const Tensor wide = Tensor::full({R, E + F}, 0.2f), basis = Tensor::full({F, C}, 0.05f), feats = Tensor::full({R, C}, 0.3f);
  const style::ContentSkip::Input in3{wide, E, acc, basis, mean, var}, in2{feats, 0, acc, Tensor(), mean, var};
  Tensor y = Tensor::zeros({R, C});
  style::ContentSkip::Context sk3, sk2;
  const double skip3 = double(R) * 2.0 * (F * C + C), skip2 = double(R) * 3.0 * C;
  row("content skip fwd (F=144)", "[4096,144]->256", best_of(reps, [&] { skip.forward_add(in3, code.std, y, &sk3); }),
      skip3, 0);
  row("content skip bwd (F=144)", "[4096,256]", best_of(reps, [&] { skip.backward(sk3, dy); }), skip3 + 2.0 * F * C, 0);
  row("content skip fwd (2D)", "[4096,256]", best_of(reps, [&] { skip.forward_add(in2, code.std, y, &sk2); }), skip2,
      0);
  row("content skip bwd (2D)", "[4096,256]", best_of(reps, [&] { skip.backward(sk2, dy); }), 4.0 * R * C, 0);
  const Tensor sict_out = Tensor::full({K, E}, 0.1f), comps = Tensor::full({K, F}, 0.2f);
  row("concat columns", "[K,32]+[K,144]", best_of(reps, [&] { nn::concat_columns(sict_out, comps); }), 0,
      2.0 * 4.0 * K * (E + F));
  const Tensor wideK = Tensor::full({K, E + F}, 0.1f);
  row("take columns", "[K,176]->[K,32]", best_of(reps, [&] { nn::take_columns(wideK, 0, E); }), 0, 2.0 * 4.0 * K * E);
  // Zero-shot composition: the region indicator of K samples (NDC space, a sphere): 12 B read + 4 written.
  const Tensor pos = Tensor::full({K, 3}, 0.1f);
  model::RegionSpace space;
  space.ndc = true;
  const model::Region sphere = model::Region::parse("sphere:0,0,-2,1", {});
  row("region indicator", "[K,3]->[K]", best_of(reps, [&] { model::region_indicator(pos, sphere, space); }), 0,
      16.0 * K);
}

}  // namespace stylerf::bench
