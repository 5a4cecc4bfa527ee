// Perf mode of the statistics, normalisation, loss, reduction and optimiser kernels (kernels/norm.cl,
// loss.cl, reduce.cl, optim.cl, elementwise.cl), part of `stylerf bench ops`. All are memory-bound:
// GB/s = (bytes of each tensor read once + each tensor written once) / time, a lower bound on traffic
// (the statistics pass reads x twice, and backward ops that recompute statistics read inputs again).
// Sizes: a [1,256,256,256] feature map (64 MiB), AdaIN at VGG relu4_1 of a 512x512 image
// ([1,512,64,64]) with a style of another size, 1e7-parameter Adam.
// Two figures per op: wall time of the whole call (which includes allocating and first-touching any
// fresh output tensor: the ops return new tensors) and the kernels alone (profiling events).
// --quick: feature maps a quarter per side, 1e6-parameter Adam, one repetition.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <functional>
#include <string>

#include "bench/bench_ops_parts.hpp"
#include "bench/timing.hpp"
#include "host/runtime.hpp"
#include "lib/nn/checks.hpp"
#include "lib/nn/ops.hpp"
#include "lib/nn/reduce_path.hpp"

namespace stylerf::bench {
namespace {

using host::Tensor;


void row(const std::string& op, const std::string& shape, double bytes, const Timing& t) {
  std::printf("  %-24s %-34s %9.3f ms %7.2f GB/s | kernels %9.3f ms %7.2f GB/s\n", op.c_str(), shape.c_str(),
              t.wall_ms, bytes / (t.wall_ms * 1e6), t.kernel_ms, bytes / (t.kernel_ms * 1e6));
  std::fflush(stdout);
}

// Distinct values per element (a ramp) so nothing is trivially constant; filled on the device.
Tensor ramp(host::Shape shape, float start, float step) {
  Tensor t = Tensor::full(shape, start, "bench tensor");
  Tensor inc = Tensor::full(shape, step, "bench tensor");
  nn::axpby(1.0f, inc, 1.0f, t);
  return t;
}

}  // namespace

void bench_ops_norm(const BenchOptions& opt) {
  const int s = opt.quick ? 64 : 256;
  const int reps = opt.quick ? 1 : std::max(opt.repeats, 3);
  std::printf("statistics / norm / loss / optimiser ops, best of %d, GB/s counts each tensor read or written once:\n",
              reps);
  {
    const host::Shape shape{1, 256, s, s};
    const std::string sh = host::shape_str(shape);
    Tensor x = ramp(shape, 0.5f, 0.25f), x2 = ramp(shape, -1.0f, 0.5f), dy = Tensor::full(shape, 0.1f);
    const double n = double(x.numel()) * 4;
    nn::ChannelStats st = nn::channel_stats_forward(x);
    Tensor g = Tensor::full(st.mean.shape(), 1.0f);
    row("channel_stats_forward", sh, n, best_of(reps, [&] { nn::channel_stats_forward(x); }));
    row("channel_stats_backward", sh, 2 * n, best_of(reps, [&] { nn::channel_stats_backward(x, st, g, g); }));
    row("instance_norm_forward", sh, 2 * n, best_of(reps, [&] { nn::instance_norm_forward(x, nullptr); }));
    row("instance_norm_backward", sh, 3 * n, best_of(reps, [&] { nn::instance_norm_backward(x, st, dy); }));
    row("mse_forward", sh, 2 * n, best_of(reps, [&] { nn::mse_forward(x, x2); }));
    row("mse_backward", sh, 3 * n, best_of(reps, [&] { nn::mse_backward(x, x2, 1.0f); }));
    row("style_loss_forward", sh, 2 * n, best_of(reps, [&] { nn::style_loss_forward(x, x2); }));
    row("style_loss_backward", sh, 3 * n, best_of(reps, [&] { nn::style_loss_backward(x, x2, 1.0f); }));
    row("sum", sh, n, best_of(reps, [&] { nn::sum(x); }));
    row("has_nonfinite", sh, n, best_of(reps, [&] { nn::has_nonfinite(x); }));
    row("axpby", sh, 3 * n, best_of(reps, [&] { nn::axpby(0.5f, x2, 0.5f, x); }));
    // The rows above take the device's default reduction path; the reductions once more on each path.
    for (auto path : {nn::ReductionPath::PerItem, nn::ReductionPath::WorkGroup}) {
      const auto old = nn::set_reduction_path(path);
      const std::string tag = path == nn::ReductionPath::PerItem ? " (per-item)" : " (work-group)";
      row("channel_stats_forward" + tag, sh, n, best_of(reps, [&] { nn::channel_stats_forward(x); }));
      row("instance_norm_backward" + tag, sh, 3 * n, best_of(reps, [&] { nn::instance_norm_backward(x, st, dy); }));
      row("mse_forward" + tag, sh, 2 * n, best_of(reps, [&] { nn::mse_forward(x, x2); }));
      row("sum" + tag, sh, n, best_of(reps, [&] { nn::sum(x); }));
      nn::set_reduction_path(old);
    }
  }
  {
    const int h = s / 4;
    const host::Shape cs{1, 512, h, h}, ss{1, 512, h + h / 2, h};
    Tensor c = ramp(cs, 0.0f, 1.0f), st = ramp(ss, 2.0f, -0.5f), dy = Tensor::full(cs, 0.1f);
    const double nc = double(c.numel()) * 4, ns = double(st.numel()) * 4;
    const std::string sh = host::shape_str(cs) + " s" + host::shape_str(ss);
    row("adain_forward", sh, 2 * nc + ns, best_of(reps, [&] { nn::adain_forward(c, st); }));
    row("adain_backward", sh, 3 * nc + 2 * ns, best_of(reps, [&] { nn::adain_backward(c, st, dy); }));
    // Towards given statistics (the vgg-adain-relu4 decoder's relu4_1 re-normalisation): no style pass.
    const nn::ChannelStats target = nn::channel_stats_forward(st);
    const std::string sht = host::shape_str(cs) + " to stats";
    row("adain_to_stats_forward", sht, 2 * nc, best_of(reps, [&] { nn::adain_to_stats_forward(c, target); }));
    row("adain_to_stats_backward", sht, 3 * nc, best_of(reps, [&] { nn::adain_to_stats_backward(c, target, dy); }));
  }
  {
    const int n = opt.quick ? 1000000 : 10000000;
    Tensor p = Tensor::full({n}, 1.0f), gr = Tensor::full({n}, 0.01f), m = Tensor::zeros({n}), v = Tensor::zeros({n});
    int step = 0;
    row("adam_step", "[" + std::to_string(n) + "]", 7.0 * n * 4,
        best_of(reps, [&] { nn::adam_step(p, gr, m, v, ++step, {}); }));
  }
}

}  // namespace stylerf::bench
