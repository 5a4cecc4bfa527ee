// `stylerf bench decoder-step --size 256 --decoder paper|fast [--json F]`: the 2D part of one style step,
// exactly the work of ../shared/anchors/torch_step.py, so the two can be compared in one run:
//   random features [1,256,S,S] (fast: [1,256,S/4,S/4]) -> decoder -> VGG relu1_1..relu4_1 ->
//   content (relu4_1 MSE) + 20 x style loss (mean/std MSE at the four taps) -> backward to the decoder's
//   weights and to the features -> Adam on the decoder (lr 1e-4, PyTorch's betas).
// The style and content targets are encoded once from random images, as the anchor does. Reports the
// median seconds per step over --repeats steps after a warm-up step, the parts (each timed in a separate
// profiled step with the queue drained between parts, so their sum is a little above the median) and the
// kernels that took the time.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <iomanip>
#include <iostream>
#include <nlohmann/json.hpp>
#include <random>
#include <vector>

#include "bench/bench.hpp"
#include "host/error.hpp"
#include "host/files.hpp"
#include "host/gemm.hpp"
#include "host/runtime.hpp"
#include "lib/nn/adam.hpp"
#include "lib/nn/conv_algo.hpp"
#include "lib/nn/decoder.hpp"
#include "lib/nn/vgg.hpp"
#include "lib/train/style_losses.hpp"

namespace stylerf::bench {
namespace {

using host::Error;
using host::Tensor;
using json = nlohmann::json;

double now_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

Tensor random_tensor(std::vector<int64_t> shape, unsigned seed, bool normal) {
  int64_t n = 1;
  for (int64_t d : shape) n *= d;
  std::mt19937 rng(seed);
  std::normal_distribution<float> nd(0.0f, 1.0f);
  std::uniform_real_distribution<float> ud(0.0f, 1.0f);
  std::vector<float> v(static_cast<size_t>(n));
  for (auto& x : v) x = normal ? nd(rng) : ud(rng);
  return Tensor::from_host(v, shape, "decoder-step input");
}

// The convs' multiply-adds x 2 of one step: decoder forward, dW and dX (dX of the first conv too: the
// features need it), VGG forward and dX (its weights are frozen).
double step_gflop(const nn::ConvStack& dec, int feat_size, int S) {
  double f = 0;
  int s = feat_size;
  for (const auto& L : dec.layers()) {
    const double one = 2.0 * L.w.value.numel() * double(s) * s;
    f += 3 * one;
    if (L.upsample) s *= 2;
  }
  const int vgg[][4] = {{3, 64, 1, 0}, {64, 64, 1, 0}, {64, 128, 2, 0}, {128, 128, 2, 0}, {128, 256, 4, 0},
                        {256, 256, 4, 0}, {256, 256, 4, 0}, {256, 256, 4, 0}, {256, 512, 8, 0}};
  for (const auto& c : vgg) {
    const double px = double(S / c[2]) * (S / c[2]);
    f += 2 * 2.0 * c[0] * c[1] * 9 * px;
  }
  return f / 1e9;
}

}  // namespace

int bench_decoder_step(const BenchOptions& opt) {
  auto& rt = host::Runtime::instance();
  const auto profile = opt.profile;
  if (profile != "paper" && profile != "fast") throw Error("bench decoder-step: --decoder must be paper or fast");
  const int S = opt.quick ? 64 : opt.size;
  if (S < 32 || S % 8) throw Error("bench decoder-step: --size must be a multiple of 8, at least 32");
  const int repeats = opt.quick ? 1 : opt.repeats;
  const bool fast = profile == "fast";
  const int FS = fast ? S / 4 : S;

  nn::ConvStack dec(fast ? nn::fast_decoder_spec() : nn::plain_decoder_spec(), 7);
  nn::VggEncoder vgg = nn::VggEncoder::load_default();
  nn::Adam adam({{"decoder", 1e-4f}}, 0.9f, 0.999f);
  std::vector<nn::Param*> params;
  dec.collect_params(params);

  nn::VggFeatures style = vgg.forward(random_tensor({1, 3, S, S}, 11, false), 4, false);
  const Tensor content41 = vgg.forward(random_tensor({1, 3, S, S}, 12, false), 4, false)[3];
  const Tensor feats = random_tensor({1, 256, FS, FS}, 13, true);
  const train::StyleLossWeights weights;  // content 1, style 20: the anchor's

  std::cout << "device: " << rt.device().describe() << "\n"
            << "decoder-step (torch_step.py's work), " << profile << " decoder " << dec.spec().describe()
            << ", features [1,256," << FS << "," << FS << "] -> " << S << "x" << S << "\n"
            << "  GEMM engine: " << host::gemm_engine_name(host::resolve_gemm_engine(host::GemmEngine::Auto))
            << "; 3x3 conv algorithm: " << nn::conv_algo_name(nn::resolve_conv_algo(nn::ConvAlgo::Auto, 256, 256, S, S))
            << " (for 256->256 at " << S << "x" << S << ")\n"
            << "  median of " << repeats << " steps after a warm-up step\n";

  // Parts of one step; lap() drains the queue and charges the time since the last lap to part i.
  const char* names[] = {"decoder fwd", "VGG fwd", "losses", "VGG bwd", "decoder bwd", "Adam"};
  constexpr int kParts = 6;
  double loss_value = 0;
  auto step = [&](double* part) {
    double t = now_s();
    auto lap = [&](int i) {
      if (!part) return;
      rt.finish();
      const double n = now_s();
      part[i] += n - t;
      t = n;
    };
    dec.zero_grad();
    nn::ConvStack::Ctx ctx;
    const Tensor y = dec.forward(feats, &ctx);
    lap(0);
    const nn::VggFeatures out = vgg.forward(y, 4, true);
    lap(1);
    nn::VggFeatures grads;
    loss_value = train::style_losses(out, content41, style, nullptr, weights, &grads).total();
    lap(2);
    const Tensor dy = vgg.backward(grads);
    lap(3);
    const Tensor dfeat = dec.backward(ctx, dy, true);
    lap(4);
    adam.step(params);
    lap(5);
    rt.finish();
  };

  step(nullptr);  // warm-up: kernels compile, buffers enter the pool
  std::vector<double> times;
  for (int r = 0; r < repeats; ++r) {
    const double t0 = now_s();
    step(nullptr);
    times.push_back(now_s() - t0);
    std::cout << "  step " << r + 1 << ": " << std::fixed << std::setprecision(3) << times.back() << " s, loss "
              << std::setprecision(4) << loss_value << "\n"
              << std::flush;
  }
  std::vector<double> sorted = times;
  std::sort(sorted.begin(), sorted.end());
  const double median = sorted.size() % 2 ? sorted[sorted.size() / 2]
                                          : 0.5 * (sorted[sorted.size() / 2 - 1] + sorted[sorted.size() / 2]);
  const double gflop = step_gflop(dec, FS, S);

  // One more step, profiled, part by part.
  double part[kParts] = {};
  rt.reset_timings();
  rt.set_profiling(true);
  step(part);
  rt.set_profiling(false);
  std::vector<std::pair<std::string, double>> kernels;
  double kernel_total = 0;
  for (const auto& k : rt.timings()) kernels.emplace_back(k.kernel, k.total_ms / 1e3), kernel_total += k.total_ms / 1e3;
  std::sort(kernels.begin(), kernels.end(), [](const auto& a, const auto& b) { return a.second > b.second; });

  std::cout << std::fixed << std::setprecision(3) << "median " << median << " s/step (min " << sorted.front()
            << ", max " << sorted.back() << "); conv work " << std::setprecision(1) << gflop << " GFLOP/step = "
            << gflop / median << " GFLOP/s effective\n  parts (s, one profiled step):\n";
  json jparts = json::object(), jkernels = json::object();
  for (int i = 0; i < kParts; ++i) {
    std::cout << "    " << std::left << std::setw(14) << names[i] << std::right << std::setprecision(3) << std::setw(8)
              << part[i] << "\n";
    jparts[names[i]] = part[i];
  }
  std::cout << "  kernels (s in that step, share of kernel time):\n";
  for (size_t i = 0; i < kernels.size(); ++i) {
    jkernels[kernels[i].first] = kernels[i].second;
    if (i < 12)
      std::cout << "    " << std::left << std::setw(28) << kernels[i].first << std::right << std::setprecision(3)
                << std::setw(8) << kernels[i].second << "  " << std::setprecision(1) << std::setw(5)
                << 100.0 * kernels[i].second / std::max(1e-9, kernel_total) << "%\n";
  }
  if (!opt.json_path.empty()) {
    json j = {{"bench", "decoder-step"}, {"device", rt.device().describe()}, {"decoder", profile}, {"size", S},
              {"gemm_engine", host::gemm_engine_name(host::resolve_gemm_engine(host::GemmEngine::Auto))},
              {"conv_algo", nn::conv_algo_name(nn::resolve_conv_algo(nn::ConvAlgo::Auto, 256, 256, S, S))},
              {"steps_s", times}, {"median_s", median}, {"gflop_per_step", gflop}, {"loss", loss_value},
              {"parts_s", jparts}, {"kernels_s", jkernels}};
    host::write_file_atomic(opt.json_path, j.dump(2) + "\n");
    std::cout << "wrote " << opt.json_path << "\n";
  }
  return 0;
}

}  // namespace stylerf::bench
