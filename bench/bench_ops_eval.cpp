// Perf mode of the evaluation kernels (part of `stylerf bench ops`): the LPIPS per-tap distance map
// (kernels/lpips.cl) at the taps of a 256x256 image (relu1_2 [1,64,256,256] and relu4_3 [1,512,32,32]),
// and the whole LPIPS (VGG-16, then AlexNet) of one 256x256 pair when the weights are installed.
// GB/s = bytes (each tensor read or written once) / kernel time. The kernels actually read the features
// twice (norms, then the distance; the backward three times), so the memory traffic is 2-3x the figure.
// --quick: a quarter per side, one repetition.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <random>
#include <string>

#include "bench/bench_ops_parts.hpp"
#include "bench/timing.hpp"
#include "host/launch.hpp"
#include "lib/eval/lpips.hpp"
#include "lib/eval/lpips_map.hpp"
#include "lib/nn/weights.hpp"

namespace stylerf::bench {
namespace {

using host::Tensor;

io::Image noise_image(int side, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  io::Image im{side, side, std::vector<float>(size_t(3) * side * side)};
  for (float& v : im.data) v = u(rng);
  return im;
}

// call: the op (allocating its output); kernel: the same kernel into a reused output.
void row(const std::string& op, const std::string& shape, double bytes, const Timing& call, const Timing& kern) {
  std::printf("  %-24s %-20s %9.3f %9.3f %8.2f\n", op.c_str(), shape.c_str(), call.wall_ms, kern.kernel_ms,
              bytes / (kern.kernel_ms * 1e6));
  std::fflush(stdout);
}

}  // namespace

void bench_ops_eval(const BenchOptions& opt) {
  const int s = opt.quick ? 64 : 256;
  const int reps = opt.quick ? 1 : std::max(opt.repeats, 3);
  std::printf("evaluation kernels (kernels/lpips.cl), best of %d\n", reps);
  std::printf("  %-24s %-20s %9s %9s %8s\n", "op", "features", "call ms", "kernel ms", "GB/s");
  for (auto [C, side] : {std::pair<int, int>{64, s}, std::pair<int, int>{512, s / 8}}) {
    const int hw = side * side;
    const Tensor a = Tensor::full({1, C, side, side}, 0.5f), b = Tensor::full({1, C, side, side}, 0.25f);
    const Tensor w = Tensor::full({C}, 0.01f), dd = Tensor::full({hw}, 1.0f);
    Tensor d({hw}), da(a.shape());
    const double fb = double(C) * hw * 4;  // one feature tensor
    const std::string shape = host::shape_str(a.shape());
    row("lpips map forward", shape, 2 * fb + 4.0 * (C + hw),
        best_of(reps, [&] { eval::lpips_distance_map(a, b, w); }),
        best_of(reps, [&] { host::launch("lpips", "lpips_distance_forward", {size_t((hw + 7) / 8)}, a, b, w, d, C, hw); }));
    row("lpips map backward", shape, 3 * fb + 4.0 * (C + hw),
        best_of(reps, [&] { eval::lpips_distance_map_backward(a, b, w, dd); }),
        best_of(reps, [&] {
          host::launch("lpips", "lpips_distance_backward", {size_t((hw + 7) / 8)}, a, b, w, dd, da, C, hw);
        }));
  }
  const io::Image x = noise_image(s, 1), y = noise_image(s, 2);
  for (eval::LpipsNet net : {eval::LpipsNet::Vgg, eval::LpipsNet::Alex}) {
    const char* name = eval::lpips_net_name(net);
    const std::string weights = nn::weights_path(eval::lpips_weights_file(net));
    if (!std::filesystem::exists(weights)) {
      std::printf("  lpips %s: not run, %s is missing (run `%s`)\n", name, weights.c_str(), nn::kFetchWeightsCommand);
      continue;
    }
    const eval::Lpips lpips = eval::Lpips::load_default(net);
    const Timing t = best_of(reps, [&] { lpips.distance(x, y); });
    std::printf("  lpips %s %dx%d: %.3f s per pair (both trunks, 5 maps, read back), %.3f s in kernels\n", name, s,
                s, t.wall_ms / 1e3, t.kernel_ms / 1e3);
  }
}

}  // namespace stylerf::bench
