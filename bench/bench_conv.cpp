// `stylerf bench conv`: conv2d forward, dX and dW time for every layer StyleRF runs at 256x256, N = 1:
//   - the decoder: eight 3x3 reflect convs at full resolution, 256-256-256-256-128-128-64-64-3;
//   - VGG-19 (AdaIN's vgg_normalised) up to relu4_1: conv0 1x1 3->3, conv1_1, conv1_2 @256, conv2_x @128,
//     conv3_x @64, conv4_1 @32.
// Each pass counts 2 * Cout * Cin*k*k * H*W flops (the GEMM's work). "aux" is the share of the time in
// our own kernels (im2col, col2im, bias), measured with event profiling; the rest is the GEMM.
// The 3x3 layers run the algorithm Auto resolves to (--conv-algo picks another). A second table is the
// accuracy-vs-time row of each 3x3 algorithm (im2col, Winograd F(2x2,3x3), F(4x4,3x3)): decoder.conv1's
// time and the max error against a double-precision reference, at unit scale and at magnitude 1e4.
// --quick: input 64x64 instead of 256x256 (each layer / 4 per side), one layer of each kind (first and
// last decoder conv, the 1x1, conv1_1, conv2_2, conv4_1), one repetition: a smoke run of seconds.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "bench/bench.hpp"
#include "bench/random_fill.hpp"
#include "bench/timing.hpp"
#include "host/files.hpp"
#include "host/runtime.hpp"
#include "lib/nn/conv_algo.hpp"
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

struct PassTime {
  double ms = 0, aux_ms = 0;
};

// Best wall time of f, and the time our own kernels took in that run (a GEMM engine may launch profiled
// kernels too; those count as GEMM).
PassTime time_pass(int repeats, const std::function<void()>& f) {
  Timing t = best_of(repeats, f);
  return {t.wall_ms, t.kernels_named({"im2col", "col2im", "bias_add", "channel_partial_sums", "linear_bias_grad"})};
}

// ---- accuracy against time, per 3x3 algorithm ---------------------------------------------------
// Double-precision references of one reflect-padded 3x3 conv, [C,H,W] images, N = 1: forward, and the
// dX / dW of L = <dy, y> (each a plain sum over the taps, no algorithm shared with the device code).
struct RefConv {
  int cin, cout, h, w;
  int src(int i, int n) const { return i < 0 ? -i : (i >= n ? 2 * n - 2 - i : i); }
  std::vector<double> forward(const std::vector<float>& x, const std::vector<float>& k) const {
    std::vector<double> y(size_t(cout) * h * w, 0.0);
    for (int o = 0; o < cout; ++o)
      for (int i = 0; i < cin; ++i)
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < 3; ++b) {
            const double kv = k[((size_t(o) * cin + i) * 3 + a) * 3 + b];
            for (int yy = 0; yy < h; ++yy) {
              const float* row = &x[(size_t(i) * h + src(yy + a - 1, h)) * w];
              double* out = &y[(size_t(o) * h + yy) * w];
              for (int xx = 0; xx < w; ++xx) out[xx] += kv * row[src(xx + b - 1, w)];
            }
          }
    return y;
  }
  // dx[i][sy][sx] += dy[o][y][x] * k[o][i][a][b] for every tap reading (sy, sx); dw likewise.
  void backward(const std::vector<float>& x, const std::vector<float>& k, const std::vector<float>& dy,
                std::vector<double>& dx, std::vector<double>& dw) const {
    dx.assign(size_t(cin) * h * w, 0.0);
    dw.assign(size_t(cout) * cin * 9, 0.0);
    for (int o = 0; o < cout; ++o)
      for (int i = 0; i < cin; ++i)
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < 3; ++b) {
            const size_t ki = ((size_t(o) * cin + i) * 3 + a) * 3 + b;
            double acc = 0;
            for (int yy = 0; yy < h; ++yy) {
              const size_t r = size_t(i) * h + src(yy + a - 1, h);
              const float* g = &dy[(size_t(o) * h + yy) * w];
              for (int xx = 0; xx < w; ++xx) {
                const int sx = src(xx + b - 1, w);
                acc += double(g[xx]) * x[r * w + sx];
                dx[r * w + sx] += double(g[xx]) * k[ki];
              }
            }
            dw[ki] = acc;
          }
  }
};

// max |got - want| / max |want|: the error relative to the output's scale (elementwise relative errors
// are meaningless where a sum cancels to ~0).
double scaled_error(const std::vector<float>& got, const std::vector<double>& want) {
  double e = 0, m = 0;
  for (size_t i = 0; i < want.size(); ++i) {
    e = std::max(e, std::abs(double(got[i]) - want[i]));
    m = std::max(m, std::abs(want[i]));
  }
  return m > 0 ? e / m : e;
}

// For each algorithm: decoder.conv1's time (256 -> 256 at size x size: forward + dX + dW, best of
// `repeats`) and its errors against the double reference on a 256 -> 256 conv at 24 x 24 (unit-scale
// inputs; inputs of magnitude 1e4 with a mean of 1e4, the case where Winograd's transforms cancel most).
nlohmann::json accuracy_vs_time(int size, int repeats) {
  std::cout << "\naccuracy vs time of the 3x3 algorithms: decoder.conv1 (256->256, " << size << "x" << size
            << ", fwd + dX + dW, ms) and max error / max |reference| of a 256->256 conv at 24x24\n";
  std::printf("%-10s | %9s %7s | %9s %9s %9s | %9s %9s %9s\n", "algorithm", "ms", "speedup", "fwd err", "dX err",
              "dW err", "fwd 1e4", "dX 1e4", "dW 1e4");
  const int C = 256, s = 24;
  const RefConv ref{C, C, s, s};
  const auto w = normal_floats(size_t(C) * C * 9, 21, 0.03f);
  const auto dy = normal_floats(size_t(C) * s * s, 22);
  struct Inputs {
    std::vector<float> x;
    std::vector<double> y, dx, dw;
  } unit, big;
  unit.x = normal_floats(size_t(C) * s * s, 23);
  big.x = normal_floats(size_t(C) * s * s, 24, 1e4f);
  for (float& v : big.x) v += 1e4f;
  for (Inputs* in : {&unit, &big}) {
    in->y = ref.forward(in->x, w);
    ref.backward(in->x, w, dy, in->dx, in->dw);
  }
  const Tensor wt = Tensor::from_host(w, {C, C, 3, 3}), dyt = Tensor::from_host(dy, {1, C, s, s});
  const int64_t hw = int64_t(size) * size;
  const Tensor xs = Tensor::from_host(normal_floats(size_t(C * hw), 25), {1, C, size, size});
  const Tensor dys = Tensor::from_host(normal_floats(size_t(C * hw), 26), {1, C, size, size});
  nlohmann::json out = nlohmann::json::array();
  double base_ms = 0;
  for (nn::ConvAlgo a : {nn::ConvAlgo::Im2col, nn::ConvAlgo::Winograd2, nn::ConvAlgo::Winograd4}) {
    const double ms = best_of(repeats, [&] {
                        nn::conv2d_forward(xs, wt, Tensor(), Padding::Reflect, a);
                        nn::conv2d_backward(xs, wt, dys, Padding::Reflect, true, true, a);
                      }).wall_ms;
    if (a == nn::ConvAlgo::Im2col) base_ms = ms;
    double err[2][3];
    int k = 0;
    for (const Inputs* in : {&unit, &big}) {
      const Tensor xt = Tensor::from_host(in->x, {1, C, s, s});
      err[k][0] = scaled_error(nn::conv2d_forward(xt, wt, Tensor(), Padding::Reflect, a).to_host(), in->y);
      const auto g = nn::conv2d_backward(xt, wt, dyt, Padding::Reflect, true, true, a);
      err[k][1] = scaled_error(g.dx.to_host(), in->dx);
      err[k][2] = scaled_error(g.dw.to_host(), in->dw);
      ++k;
    }
    std::printf("%-10s | %9.1f %6.2fx | %9.2e %9.2e %9.2e | %9.2e %9.2e %9.2e\n", nn::conv_algo_name(a), ms,
                base_ms / ms, err[0][0], err[0][1], err[0][2], err[1][0], err[1][1], err[1][2]);
    std::fflush(stdout);
    out.push_back({{"algorithm", nn::conv_algo_name(a)}, {"ms", ms}, {"speedup_vs_im2col", base_ms / ms},
                   {"err_unit", {{"fwd", err[0][0]}, {"dx", err[0][1]}, {"dw", err[0][2]}}},
                   {"err_1e4", {{"fwd", err[1][0]}, {"dx", err[1][1]}, {"dw", err[1][2]}}}});
  }
  return out;
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
    Tensor x = Tensor::from_host(normal_floats(size_t(L.cin * hw), 1), {1, L.cin, L.size, L.size});
    Tensor w = Tensor::from_host(normal_floats(size_t(L.cout) * L.cin * L.k * L.k, 2, 0.05f),
                                 {L.cout, L.cin, L.k, L.k});
    Tensor b = Tensor::zeros({L.cout});
    Tensor dy = Tensor::from_host(normal_floats(size_t(L.cout * hw), 3), {1, L.cout, L.size, L.size});
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
  const std::string algo_used = nn::conv_algo_name(nn::resolve_conv_algo(nn::ConvAlgo::Auto, 256, 256, size, size));
  std::printf("%-16s %5s %5s %4s %2s | %9.1f %7.2f %5s | %9.1f %7.2f %5s | %9.1f %7.2f\n", "total", "", "", "", "",
              tot_fwd, gf(tot_fwd), "", tot_dx, gf(tot_dx), "", tot_dw, gf(tot_dw));
  std::cout << "(3x3 layers ran " << algo_used << "; GFLOP/s counts the direct conv's multiply-adds)\n";
  const nlohmann::json accuracy = accuracy_vs_time(size, repeats);
  if (!opt.json_path.empty()) {
    nlohmann::json j = {{"bench", "conv"},
                        {"device", rt.device().describe()},
                        {"size", size},
                        {"repeats", repeats},
                        {"conv_algo", algo_used},
                        {"layers", out},
                        {"accuracy_vs_time", accuracy},
                        {"total", {{"fwd_ms", tot_fwd}, {"dx_ms", tot_dx}, {"dw_ms", tot_dw}, {"gflop", tot_flop / 1e9}}}};
    host::write_file_atomic(opt.json_path, j.dump(2) + "\n");
    std::cout << "wrote " << opt.json_path << "\n";
  }
  return 0;
}

}  // namespace stylerf::bench
