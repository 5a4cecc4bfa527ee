// Perf mode of the spatial kernels of kernels/nn.cl (part of `stylerf bench ops`): relu, 2x2 max pool,
// x2 upsample, the polyphase pool and its interleave, im2col, col2im at the sizes StyleRF runs them (256x256
// images); of kernels/winograd.cl's F(4x4) tile transforms (input, output, their adjoints, the gather);
// and of kernels/strided.cl
// at AlexNet LPIPS's sizes for a 256x256 image: 3x3 stride-2 max pool, the strided im2col / col2im of
// conv1 (11x11/4/2) and conv2 (5x5/1/2), and the whole strided conv2d (im2col + GEMM) in GFLOP/s. The
// kernels are memory-bound, so their figure is GB/s = (bytes read once + bytes written) / time; im2col
// reads each input element about (k/s)^2 times from cache, which is not counted.
// --quick: every tensor a quarter per side of the full size, one repetition.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <functional>
#include <string>

#include "bench/bench_ops_parts.hpp"
#include "bench/timing.hpp"
#include "host/launch.hpp"
#include "host/runtime.hpp"
#include "lib/nn/ops.hpp"

namespace stylerf::bench {
namespace {

using host::Tensor;


// call: the nn:: op (allocates its output, as real use does: fresh pages are faulted in by the kernel);
// kernel: the same kernel launched into a reused output; GB/s from the reused-output kernel time.
void row(const std::string& op, const std::string& shape, double bytes, const Timing& call, const Timing& kern) {
  std::printf("  %-20s %-24s %9.3f %9.3f %8.2f\n", op.c_str(), shape.c_str(), call.wall_ms, kern.kernel_ms,
              bytes / (kern.kernel_ms * 1e6));
  std::fflush(stdout);
}

size_t g8(int64_t n) { return size_t((n + 7) / 8); }

}  // namespace

void bench_ops_spatial(const BenchOptions& opt) {
  const int s = opt.quick ? 64 : 256;
  const int reps = opt.quick ? 1 : std::max(opt.repeats, 3);
  std::printf("spatial ops (kernels/nn.cl), best of %d; GB/s = bytes (each tensor read or written once) / kernel "
              "time\n  call ms: the op, allocating its output; kernel ms: the kernel alone into a reused output\n",
              reps);
  std::printf("  %-20s %-24s %9s %9s %8s\n", "op", "input", "call ms", "kernel ms", "GB/s");

  {  // relu on a decoder activation [1,256,s,s]
    Tensor x = Tensor::full({1, 256, s, s}, -0.5f), y = nn::relu_forward(x), dy = Tensor::full(x.shape(), 1.0f);
    Tensor dx = Tensor::zeros(x.shape());
    const int n = int(x.numel());
    const double b = double(n) * 4;
    const std::string shape = host::shape_str(x.shape());
    row("relu_forward", shape, 2 * b, best_of(reps, [&] { nn::relu_forward(x); }),
        best_of(reps, [&] { host::launch("nn", "relu_forward", {g8(n)}, x, y, n); }));
    row("relu_backward", shape, 3 * b, best_of(reps, [&] { nn::relu_backward(y, dy); }),
        best_of(reps, [&] { host::launch("nn", "relu_backward", {g8(n)}, y, dy, dx, n); }));
  }
  {  // maxpool after VGG conv1_2: [1,64,s,s]
    Tensor x = Tensor::full({1, 64, s, s}, 1.0f), dy = Tensor::full({1, 64, s / 2, s / 2}, 1.0f);
    Tensor y = Tensor::zeros(dy.shape()), dx = Tensor::zeros(x.shape());
    const double b = double(x.numel()) * 4;
    const std::string shape = host::shape_str(x.shape());
    const size_t ho = size_t(s / 2), nc = 64;
    row("maxpool2x2_forward", shape, 1.25 * b, best_of(reps, [&] { nn::maxpool2x2_forward(x); }),
        best_of(reps, [&] { host::launch("nn", "maxpool2x2_forward", {ho, nc}, x, y, s, s); }));
    row("maxpool2x2_backward", shape, 2.25 * b, best_of(reps, [&] { nn::maxpool2x2_backward(x, dy); }),
        best_of(reps, [&] { host::launch("nn", "maxpool2x2_backward", {ho, nc}, x, dy, dx, s, s); }));
  }
  {  // upsample [1,128,s/2,s/2] -> [1,128,s,s]
    Tensor x = Tensor::full({1, 128, s / 2, s / 2}, 1.0f), dy = Tensor::full({1, 128, s, s}, 1.0f);
    Tensor y = Tensor::zeros(dy.shape()), dx = Tensor::zeros(x.shape());
    const double b = double(x.numel()) * 4;
    const std::string shape = host::shape_str(x.shape());
    const size_t h = size_t(s / 2), nc = 128;
    row("upsample2x_forward", shape, 5 * b, best_of(reps, [&] { nn::upsample2x_forward(x); }),
        best_of(reps, [&] { host::launch("nn", "upsample2x_forward", {h, nc}, x, y, s / 2, s / 2); }));
    row("upsample2x_backward", shape, 5 * b, best_of(reps, [&] { nn::upsample2x_backward(dy); }),
        best_of(reps, [&] { host::launch("nn", "upsample2x_backward", {h, nc}, dy, dx, s / 2, s / 2); }));
  }
  {  // the VGG tail's polyphase pool and the decoder's interleave at a 256x256 patch's relu3_1 size
     // [1,256,s/4,s/4] -> [4,256,s/8,s/8] (decoder_phases), and [4,256,s/8,s/8] -> [1,256,s/4,s/4]
    const int q = s / 4;
    Tensor x = Tensor::full({1, 256, q, q}, 1.0f), dy = Tensor::full({4, 256, q / 2, q / 2}, 1.0f);
    Tensor y = Tensor::zeros(dy.shape()), dx = Tensor::zeros(x.shape());
    const double b = double(x.numel()) * 4;
    const std::string shape = host::shape_str(x.shape());
    const int nc = 256;
    const size_t po = size_t(q / 2) * size_t(q / 2), pi = size_t(q) * size_t(q);
    row("maxpool_phases_fwd", shape, 2 * b, best_of(reps, [&] { nn::maxpool2x2_phases_forward(x); }),
        best_of(reps, [&] { host::launch("nn", "maxpool2x2_phases_forward", {po, size_t(4 * nc)}, x, y, nc, q, q); }));
    row("maxpool_phases_bwd", shape, 3 * b, best_of(reps, [&] { nn::maxpool2x2_phases_backward(x, dy); }),
        best_of(reps, [&] { host::launch("nn", "maxpool2x2_phases_backward", {pi, size_t(nc)}, x, dy, dx, nc, q, q); }));
    row("phase_interleave_fwd", host::shape_str(y.shape()), 2 * b, best_of(reps, [&] { nn::phase_interleave_forward(y); }),
        best_of(reps, [&] { host::launch("nn", "phase_interleave_forward", {pi, size_t(nc)}, y, dx, nc, q / 2, q / 2); }));
    row("phase_interleave_bwd", shape, 2 * b, best_of(reps, [&] { nn::phase_interleave_backward(x); }),
        best_of(reps, [&] { host::launch("nn", "phase_interleave_backward", {po, size_t(4 * nc)}, x, y, nc, q / 2, q / 2); }));
  }
  // im2col / col2im of VGG conv1_2 (64 channels at s x s, 3x3 reflect): col is [576, s*s]; and of the
  // decoder's 256-channel layer at s/2 (col [2304, s*s/4]).
  for (int c : {64, 256}) {
    const int h = c == 64 ? s : s / 2;
    const int ckk = c * 9;
    Tensor x = Tensor::full({1, c, h, h}, 1.0f), dx = Tensor::zeros({1, c, h, h});
    Tensor col = Tensor::zeros({int64_t(ckk), int64_t(h) * h}, "bench col");
    const double xb = double(x.numel()) * 4, colb = double(col.numel()) * 4;
    const std::string shape = host::shape_str(x.shape()) + " k3";
    for (int mode : {0, 1}) {
      const std::string m = mode ? " reflect" : " zero";
      // Launched directly into reused buffers (conv2d keeps its col scratch), so call == kernel.
      Timing t = best_of(reps, [&] {
        host::launch("nn", "im2col", {size_t(h), size_t(ckk)}, x, 0, col, c, h, h, 3, mode, 0, h);
      });
      row("im2col" + m, shape, xb + colb, t, t);
      t = best_of(reps, [&] {
        host::launch("nn", "col2im", {size_t(h), size_t(c)}, col, dx, 0, c, h, h, 3, mode, 0, h, 0, h, 0);
      });
      row("col2im" + m, shape, xb + colb, t, t);
    }
  }

  // ---- kernels/winograd.cl, F(4x4, 3x3) (the Auto conv algorithm): the tile transforms of VGG conv1_2
  // (64 channels at s x s) and of a 256-channel layer at s/4 (relu3_1 of an s x s patch). Bytes: the
  // image once and the alpha^2 = 36 transformed planes of [C][T] once (T tiles of 4x4 pixels).
  for (int c : {64, 256}) {
    const int h = c == 64 ? s : s / 4, m = 4, alpha = 6, th = (h + m - 1) / m, T = th * th;
    const std::string opts = "-DWINO_M=4", shape = host::shape_str({1, c, h, h});
    Tensor x = Tensor::full({1, c, h, h}, 1.0f), dx = Tensor::zeros(x.shape()), b = Tensor::zeros({c});
    Tensor V = Tensor::zeros({int64_t(alpha) * alpha, c, T}, "bench winograd tiles");
    const double xb = double(x.numel()) * 4, vb = double(V.numel()) * 4;
    const size_t groups = size_t(th) * size_t((th + 7) / 8);
    const bool cpu = host::Runtime::instance().device().type & CL_DEVICE_TYPE_CPU;
    const host::Range local(cpu ? 8 : 64, 1);  // as lib/nn/conv_winograd.cpp launches them
    Timing t = best_of(reps, [&] {
      host::launch_with_local("winograd", "wino_input_transform", opts, {groups, size_t(c)}, local, x, V, c, h, h, th,
                              th, T, 1);
    });
    row("wino_input_fwd", shape, xb + vb, t, t);
    t = best_of(reps, [&] {
      host::launch_with_local("winograd", "wino_output_transform", opts, {groups, size_t(c)}, local, V, b, 1, dx, c, h,
                              h, th, th, T);
    });
    row("wino_output_fwd", shape, xb + vb, t, t);
    t = best_of(reps, [&] {
      host::launch_with_local("winograd", "wino_output_backward", opts, {groups, size_t(c)}, local, x, V, c, h, h, th,
                              th, T);
    });
    row("wino_output_bwd", shape, xb + vb, t, t);
    t = best_of(reps, [&] {
      host::launch_with_local("winograd", "wino_input_backward", opts, {groups, size_t(c)}, local, V, c, th, th, T);
    });
    row("wino_input_bwd", shape, 2 * vb, t, t);
    t = best_of(reps, [&] {
      host::launch_with_local("winograd", "wino_input_gather", opts, {groups, size_t(c)}, local, V, dx, c, h, h, th,
                              th, T);
    });
    row("wino_input_gather", shape, xb + vb, t, t);
  }

  // ---- kernels/strided.cl at AlexNet's sizes (LPIPS --net alex on an s x s image) ----
  const int c1 = nn::conv2d_output_size(s, 11, 4, 2);  // 63 at 256
  const int p1 = (c1 - 3) / 2 + 1;                     // 31
  {  // 3x3 stride-2 max pool after conv1: [1,64,c1,c1] -> [1,64,p1,p1]
    Tensor x = Tensor::full({1, 64, c1, c1}, 1.0f), dy = Tensor::full({1, 64, p1, p1}, 1.0f);
    Tensor y = Tensor::zeros(dy.shape()), dx = Tensor::zeros(x.shape());
    const double xb = double(x.numel()) * 4, yb = double(y.numel()) * 4;
    const std::string shape = host::shape_str(x.shape()) + " 3/2";
    row("maxpool_forward", shape, xb + yb, best_of(reps, [&] { nn::maxpool_forward(x, 3, 2); }),
        best_of(reps, [&] {
          host::launch("strided", "maxpool_forward", {size_t(p1), 64}, x, y, c1, c1, 3, 2, p1, p1);
        }));
    row("maxpool_backward", shape, 2 * xb + yb, best_of(reps, [&] { nn::maxpool_backward(x, dy, 3, 2); }),
        best_of(reps, [&] {
          host::launch("strided", "maxpool_backward", {size_t(c1), 64}, x, dy, dx, c1, c1, 3, 2, p1, p1);
        }));
  }
  struct Conv {
    const char* name;
    int cin, cout, size, k, stride, pad;
  };
  const Conv convs[] = {{"alex conv1", 3, 64, s, 11, 4, 2}, {"alex conv2", 64, 192, p1, 5, 1, 2}};
  for (const Conv& c : convs) {  // im2col / col2im into reused buffers (call == kernel)
    const int ho = nn::conv2d_output_size(c.size, c.k, c.stride, c.pad);
    const int ckk = c.cin * c.k * c.k;
    Tensor x = Tensor::full({1, c.cin, c.size, c.size}, 1.0f), dx = Tensor::zeros(x.shape());
    Tensor col = Tensor::zeros({int64_t(ckk), int64_t(ho) * ho}, "bench col");
    const double xb = double(x.numel()) * 4, colb = double(col.numel()) * 4;
    const std::string shape = host::shape_str(x.shape()) + " k" + std::to_string(c.k) + "/" +
                              std::to_string(c.stride) + "/" + std::to_string(c.pad);
    Timing t = best_of(reps, [&] {
      host::launch("strided", "im2col_strided", {size_t(ho), size_t(ckk)}, x, 0, col, c.cin, c.size, c.size, c.k,
                   c.stride, c.pad, ho, 0, ho);
    });
    row("im2col_strided", shape, xb + colb, t, t);
    t = best_of(reps, [&] {
      host::launch("strided", "col2im_strided", {size_t(c.size), size_t(c.cin)}, col, dx, 0, c.cin, c.size, c.size,
                   c.k, c.stride, c.pad, ho, 0, ho, 0, c.size, 0);
    });
    row("col2im_strided", shape, xb + colb, t, t);
  }
  // The whole strided conv (im2col + GEMM + bias; backward: dW, db and dX), GFLOP/s = 2 * Cout * CKK * HoWo
  // per pass (backward: two passes) / wall time.
  std::printf("  %-20s %-30s %9s %9s %8s\n", "conv2d_strided", "input k/s/p -> Cout", "fwd ms", "bwd ms",
              "GFLOP/s f/b");
  for (const Conv& c : convs) {
    const int ho = nn::conv2d_output_size(c.size, c.k, c.stride, c.pad);
    Tensor x = Tensor::full({1, c.cin, c.size, c.size}, 0.5f), w = Tensor::full({c.cout, c.cin, c.k, c.k}, 0.01f);
    Tensor b = Tensor::zeros({c.cout}), dy = Tensor::full({1, c.cout, ho, ho}, 1.0f);
    const double flop = 2.0 * c.cout * c.cin * c.k * c.k * double(ho) * ho;
    const Timing f = best_of(reps, [&] { nn::conv2d_strided_forward(x, w, b, c.stride, c.pad); });
    const Timing g = best_of(reps, [&] { nn::conv2d_strided_backward(x, w, dy, c.stride, c.pad, true, true); });
    const std::string shape = host::shape_str(x.shape()) + " " + std::to_string(c.k) + "/" + std::to_string(c.stride) +
                              "/" + std::to_string(c.pad) + " -> " + std::to_string(c.cout);
    std::printf("  %-20s %-30s %9.3f %9.3f %4.1f/%-4.1f\n", c.name, shape.c_str(), f.wall_ms, g.wall_ms,
                flop / (f.wall_ms * 1e6), 2 * flop / (g.wall_ms * 1e6));
    std::fflush(stdout);
  }
}

}  // namespace stylerf::bench
