// Perf mode of the background shell's kernels (kernels/background_shell.cl, part of `stylerf bench ops`):
// the taps, the forward, the opacity's gradient and the map's (with the host's grouping of the taps by
// texel, which the call time includes), at the sizes the stages run them: a density step's 4096 rays of
// colour, a feature step's 4096 rays of 256 features, and a stylised 544x960 frame's 136x240 blocks.
// GB/s = (bytes of each tensor read or written once) / kernel time; the map is read through the taps,
// four texel rows a ray, counted as such.
// --quick: a quarter of the rays, one repetition.
#include <algorithm>
#include <cstdio>
#include <string>
#include <vector>

#include "bench/bench_ops_parts.hpp"
#include "bench/random_fill.hpp"
#include "bench/timing.hpp"
#include "lib/render/background_shell.hpp"

namespace stylerf::bench {
namespace {

using host::Tensor;

void row(const std::string& op, const std::string& shape, double bytes, const Timing& t) {
  std::printf("  %-26s %-20s %9.3f %9.3f %8.2f\n", op.c_str(), shape.c_str(), t.wall_ms, t.kernel_ms,
              bytes / (t.kernel_ms * 1e6));
  std::fflush(stdout);
}

void case_of(const char* what, int64_t R, int C, int reps) {
  const int H = 128, W = 256;
  // Rays from inside the unit sphere in all directions; a shell of radius 3, as a capture's.
  const Tensor o = Tensor::from_host(uniform_floats(size_t(R) * 3, 1, -0.5f, 0.5f), {R, 3});
  const Tensor d = Tensor::from_host(uniform_floats(size_t(R) * 3, 2, -1.0f, 1.0f), {R, 3});
  const Tensor acc = Tensor::from_host(uniform_floats(size_t(R), 3, 0.0f, 1.0f), {R});
  const Tensor map = Tensor::from_host(uniform_floats(size_t(H) * W * C, 4, -1.0f, 1.0f), {H * W, C});
  Tensor out = Tensor::zeros({R, C}), dout = Tensor::full({R, C}, 1.0f), dacc = Tensor::zeros({R}),
         dmap = Tensor::zeros({H * W, C});
  render::ShellTaps taps = render::background_shell_taps(o, d, 3.0f, H, W);
  const std::string shape = std::string(what) + " " + std::to_string(R) + "x" + std::to_string(C);
  const double rows = double(R) * C * 4, gathered = 4.0 * rows, tap_bytes = double(R) * 4 * 8;
  row("background_shell_taps", shape, double(R) * 24 + tap_bytes,
      best_of(reps, [&] { taps = render::background_shell_taps(o, d, 3.0f, H, W); }));
  row("background_shell_forward", shape, 2 * rows + gathered + tap_bytes + double(R) * 4,
      best_of(reps, [&] { render::background_shell_forward(out, acc, map, taps); }));
  row("background_shell_dacc", shape, rows + gathered + tap_bytes + double(R) * 8,
      best_of(reps, [&] { render::background_shell_backward(dout, acc, map, taps, &dacc, false, nullptr); }));
  row("background_shell_dmap", shape, 4 * rows + tap_bytes + double(R) * 4,
      best_of(reps, [&] { render::background_shell_backward(dout, acc, map, taps, nullptr, false, &dmap); }));
}

}  // namespace

void bench_ops_shell(const BenchOptions& opt) {
  const int reps = opt.quick ? 1 : std::max(opt.repeats, 3);
  const int64_t q = opt.quick ? 4 : 1;
  std::printf("background shell (kernels/background_shell.cl), 128x256 map, best of %d; GB/s = bytes / kernel time\n"
              "  call ms: the op as the stages call it (dmap: with the host's grouping of the taps)\n",
              reps);
  std::printf("  %-26s %-20s %9s %9s %8s\n", "op", "rays x channels", "call ms", "kernel ms", "GB/s");
  case_of("density step", 4096 / q, 3, reps);
  case_of("feature step", 4096 / q, 256, reps);
  case_of("frame blocks", 136 * 240 / q, 256, reps);
}

}  // namespace stylerf::bench
