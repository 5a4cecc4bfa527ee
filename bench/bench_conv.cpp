// `stylerf bench conv`: conv2d forward, dX and dW time for every layer StyleRF runs at 256x256, N = 1:
//   - the decoder: eight 3x3 reflect convs at full resolution, 256-256-256-256-128-128-64-64-3;
//   - VGG-19 (AdaIN's vgg_normalised) up to relu4_1: conv0 1x1 3->3, conv1_1, conv1_2 @256, conv2_x @128,
//     conv3_x @64, conv4_1 @32.
// Each pass counts 2 * Cout * Cin*k*k * H*W flops (the GEMM's work). "aux" is the share of the time in
// our own kernels (im2col, col2im, bias), measured with event profiling; the rest is the GEMM.
// --quick: input 64x64 instead of 256x256 (each layer / 4 per side), one layer of each kind (first and
// last decoder conv, the 1x1, conv1_1, conv2_2, conv4_1), one repetition: a smoke run of seconds.
#include <algorithm>
#include <chrono>
#include <functional>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "bench/bench.hpp"
#include "bench/timing.hpp"
#include "host/files.hpp"
#include "host/runtime.hpp"
#include "lib/nn/ops.hpp"

namespace stylerf::bench {
namespace {

using nn::Padding;
using host::Tensor;

struct Layer {
  std::string name;
  int cin, cout, size, k;
  Padding pad;
};

std::vector<Layer> layers(int s) {
  std::vector<Layer> v;
  const int dec[9] = {256, 256, 256, 256, 128, 128, 64, 64, 3};
  for (int i = 0; i < 8; ++i)
    v.push_back({"decoder.conv" + std::to_string(i + 1), dec[i], dec[i + 1], s, 3, Padding::Reflect});
  v.push_back({"vgg.conv0", 3, 3, s, 1, Padding::Reflect});
  v.push_back({"vgg.conv1_1", 3, 64, s, 3, Padding::Reflect});
  v.push_back({"vgg.conv1_2", 64, 64, s, 3, Padding::Reflect});
  v.push_back({"vgg.conv2_1", 64, 128, s / 2, 3, Padding::Reflect});
  v.push_back({"vgg.conv2_2", 128, 128, s / 2, 3, Padding::Reflect});
  v.push_back({"vgg.conv3_1", 128, 256, s / 4, 3, Padding::Reflect});
  for (int i = 2; i <= 4; ++i) v.push_back({"vgg.conv3_" + std::to_string(i), 256, 256, s / 4, 3, Padding::Reflect});
  v.push_back({"vgg.conv4_1", 256, 512, s / 8, 3, Padding::Reflect});
  return v;
}

std::vector<float> random_normal(size_t n, unsigned seed, float stddev = 1.0f) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> d(0.0f, stddev);
  std::vector<float> v(n);
  for (auto& x : v) x = d(rng);
  return v;
}

struct PassTime {
  double ms = 0, aux_ms = 0;
};

// Best wall time of f, and the time our own kernels took in that run (a GEMM engine may launch profiled
// kernels too; those count as GEMM).
PassTime time_pass(int repeats, const std::function<void()>& f) {
  Timing t = best_of(repeats, f);
  return {t.wall_ms, t.kernels_named({"im2col", "col2im", "bias_add", "bias_grad"})};
}

}  // namespace

int bench_conv(const BenchOptions& opt) {
  auto& rt = host::Runtime::instance();
  const int size = opt.quick ? 64 : 256;
  const int repeats = opt.quick ? 1 : opt.repeats;
  std::cout << "device: " << rt.device().describe() << "\n"
            << "conv2d, N=1, input " << size << "x" << size << ", best of " << repeats
            << " after a warm-up; GFLOP/s = 2*Cout*Cin*k*k*H*W / time; aux = im2col/col2im/bias share\n";
  std::printf("%-16s %5s %5s %4s %2s | %9s %7s %5s | %9s %7s %5s | %9s %7s %5s\n", "layer", "Cin", "Cout", "HxW",
              "k", "fwd ms", "GFLOP/s", "aux%", "dx ms", "GFLOP/s", "aux%", "dW ms", "GFLOP/s", "aux%");
  nlohmann::json out = nlohmann::json::array();
  double tot_fwd = 0, tot_dx = 0, tot_dw = 0, tot_flop = 0;
  std::vector<Layer> todo = layers(size);
  if (opt.quick) {
    const std::vector<std::string> keep = {"decoder.conv1", "decoder.conv8", "vgg.conv0", "vgg.conv1_1",
                                           "vgg.conv2_2", "vgg.conv4_1"};
    todo.erase(std::remove_if(todo.begin(), todo.end(),
                              [&](const Layer& L) { return std::find(keep.begin(), keep.end(), L.name) == keep.end(); }),
               todo.end());
  }
  for (const Layer& L : todo) {
    const int64_t hw = int64_t(L.size) * L.size;
    Tensor x = Tensor::from_host(random_normal(size_t(L.cin * hw), 1), {1, L.cin, L.size, L.size});
    Tensor w = Tensor::from_host(random_normal(size_t(L.cout) * L.cin * L.k * L.k, 2, 0.05f),
                                 {L.cout, L.cin, L.k, L.k});
    Tensor b = Tensor::zeros({L.cout});
    Tensor dy = Tensor::from_host(random_normal(size_t(L.cout * hw), 3), {1, L.cout, L.size, L.size});
    const double flop = 2.0 * L.cout * L.cin * L.k * L.k * double(hw);
    PassTime fwd = time_pass(repeats, [&] { nn::conv2d_forward(x, w, b, L.pad); });
    PassTime dx = time_pass(repeats, [&] { nn::conv2d_backward(x, w, dy, L.pad, true, false); });
    PassTime dw = time_pass(repeats, [&] { nn::conv2d_backward(x, w, dy, L.pad, false, true); });
    auto gf = [&](double ms) { return flop / (ms * 1e6); };
    auto pct = [](const PassTime& p) { return 100.0 * p.aux_ms / p.ms; };
    std::printf("%-16s %5d %5d %4d %2d | %9.2f %7.2f %5.1f | %9.2f %7.2f %5.1f | %9.2f %7.2f %5.1f\n",
                L.name.c_str(), L.cin, L.cout, L.size, L.k, fwd.ms, gf(fwd.ms), pct(fwd), dx.ms, gf(dx.ms), pct(dx),
                dw.ms, gf(dw.ms), pct(dw));
    std::fflush(stdout);
    tot_fwd += fwd.ms, tot_dx += dx.ms, tot_dw += dw.ms, tot_flop += flop;
    out.push_back({{"layer", L.name}, {"cin", L.cin}, {"cout", L.cout}, {"size", L.size}, {"k", L.k},
                   {"gflop", flop / 1e9}, {"fwd_ms", fwd.ms}, {"fwd_aux_ms", fwd.aux_ms}, {"dx_ms", dx.ms},
                   {"dx_aux_ms", dx.aux_ms}, {"dw_ms", dw.ms}, {"dw_aux_ms", dw.aux_ms}});
  }
  auto gf = [&](double ms) { return tot_flop / (ms * 1e6); };
  std::printf("%-16s %5s %5s %4s %2s | %9.1f %7.2f %5s | %9.1f %7.2f %5s | %9.1f %7.2f\n", "total", "", "", "", "",
              tot_fwd, gf(tot_fwd), "", tot_dx, gf(tot_dx), "", tot_dw, gf(tot_dw));
  if (!opt.json_path.empty()) {
    nlohmann::json j = {{"bench", "conv"},
                        {"device", rt.device().describe()},
                        {"size", size},
                        {"repeats", repeats},
                        {"layers", out},
                        {"total", {{"fwd_ms", tot_fwd}, {"dx_ms", tot_dx}, {"dw_ms", tot_dw}, {"gflop", tot_flop / 1e9}}}};
    host::write_file_atomic(opt.json_path, j.dump(2) + "\n");
    std::cout << "wrote " << opt.json_path << "\n";
  }
  return 0;
}

}  // namespace stylerf::bench
