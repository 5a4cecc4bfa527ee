// Perf mode of the layout ops (kernels/layout.cl) and nn::linear (GEMMs + kernels/linear.cl), part of
// `stylerf bench ops`, at the sizes StyleRF runs them:
//   - rows <-> image of a 256x256 patch of 256-channel features ([65536, 256] <-> [1,256,256,256]):
//     memory-bound, GB/s = (bytes read + bytes written) / kernel time;
//   - linear forward / dx / dW+db (GFLOP/s = 2 * N * in * out / wall time of the pass): the feature
//     grid's basis matrix on a batch of rays (4096 x 144 -> 256, Blender ranks 48 * 3) and the DST's
//     1024 -> 1024 map on one row (a matrix-vector product: memory-bound, so GB/s of W is shown too).
// --quick: the patch is 64x64 and the ray batch 1024, one repetition.
#include <algorithm>
#include <cstdio>
#include <string>

#include "bench/bench_ops_parts.hpp"
#include "bench/timing.hpp"
#include "host/launch.hpp"
#include "lib/nn/layout.hpp"
#include "lib/nn/linear.hpp"

namespace stylerf::bench {
namespace {

using host::Tensor;

void layout_row(const std::string& op, const std::string& shape, double bytes, const Timing& call,
                const Timing& kern) {
  std::printf("  %-24s %-22s %9.3f %9.3f %8.2f\n", op.c_str(), shape.c_str(), call.wall_ms, kern.kernel_ms,
              bytes / (kern.kernel_ms * 1e6));
  std::fflush(stdout);
}

void linear_row(const std::string& pass, int n, int in, int out, const Timing& t) {
  const double flops = 2.0 * n * in * out, wbytes = 4.0 * in * out;
  std::printf("  %-12s N=%-5d %4d -> %-5d %9.3f %9.2f %8.2f\n", pass.c_str(), n, in, out, t.wall_ms,
              flops / (t.wall_ms * 1e6), wbytes / (t.wall_ms * 1e6));
  std::fflush(stdout);
}

}  // namespace

void bench_ops_layout(const BenchOptions& opt) {
  const int s = opt.quick ? 64 : 256, C = 256;
  const int reps = opt.quick ? 1 : std::max(opt.repeats, 3);
  std::printf("layout ops (kernels/layout.cl), best of %d; GB/s = bytes read + written / kernel time\n"
              "  call ms: the op, allocating its output; kernel ms: the transpose alone into a reused output\n",
              reps);
  std::printf("  %-24s %-22s %9s %9s %8s\n", "op", "input", "call ms", "kernel ms", "GB/s");
  {
    const int hw = s * s;
    Tensor rows = Tensor::full({hw, C}, 1.0f), img = Tensor::full({1, C, s, s}, 1.0f);
    Tensor img_out = Tensor::zeros(img.shape()), rows_out = Tensor::zeros(rows.shape());
    const double b = 2.0 * double(rows.bytes());
    const size_t tiles_r = size_t((hw + 15) / 16), tiles_c = size_t(C / 16);
    layout_row("rows_to_image", host::shape_str(rows.shape()), b, best_of(reps, [&] { nn::rows_to_image(rows, s, s); }),
               best_of(reps, [&] {
                 host::launch("layout", "transpose2d", {tiles_r, tiles_c}, rows, 0, img_out, 0, hw, C);
               }));
    layout_row("image_to_rows", host::shape_str(img.shape()), b, best_of(reps, [&] { nn::image_to_rows(img); }),
               best_of(reps, [&] {
                 host::launch("layout", "transpose2d", {tiles_c, tiles_r}, img, 0, rows_out, 0, C, hw);
               }));
  }

  std::printf("nn::linear (host GEMM + kernels/linear.cl), best of %d wall times; GFLOP/s = 2*N*in*out / time, "
              "W GB/s = bytes of W / time\n",
              reps);
  std::printf("  %-12s %-20s %9s %9s %8s\n", "pass", "shape", "ms", "GFLOP/s", "W GB/s");
  struct Shape {
    int n, in, out;
  };
  const Shape shapes[] = {{opt.quick ? 1024 : 4096, 144, 256}, {1, 1024, 1024}};
  for (const Shape& sh : shapes) {
    Tensor x = Tensor::full({sh.n, sh.in}, 0.5f), w = Tensor::full({sh.in, sh.out}, 0.01f);
    Tensor b = Tensor::full({sh.out}, 0.1f), dy = Tensor::full({sh.n, sh.out}, 1.0f);
    nn::Param pw("w", 0, w), pb("b", 0, b);
    linear_row("forward", sh.n, sh.in, sh.out, best_of(reps, [&] { nn::linear_forward(x, w, b); }));
    linear_row("dx", sh.n, sh.in, sh.out, best_of(reps, [&] { nn::linear_backward(x, w, dy, true, false, false); }));
    // The module form: dW and db accumulated into the Params' grads (GEMM beta = 1, bias column sums).
    linear_row("dW+db accum", sh.n, sh.in, sh.out, best_of(reps, [&] { nn::linear_backward(x, pw, &pb, dy, false); }));
  }
}

}  // namespace stylerf::bench
