// Benchmarks, run through `stylerf bench <name>`. Each prints a table and optionally writes JSON.
#pragma once
#include <string>
#include <vector>

namespace stylerf::bench {

struct BenchOptions {
  std::string json_path;  // empty: no JSON
  int repeats = 3;        // timed repetitions after one warm-up
  bool quick = false;     // smaller shapes, for smoke runs in the test suite / README demo
  // bench density only: training seconds per scene curve and per knob row (0: the mode's default), and
  // which parts to run ("lego", "fern", "knobs"; empty: all).
  double budget_s = 0, knob_budget_s = 0;
  std::vector<std::string> parts;
  // bench patch only: a density or feature checkpoint whose geometry to render (empty: a synthetic
  // geometry where every sample counts), the stage, the decoder profile, the patch side, and (stage 3) the
  // style decoder (stage2 | vgg-adain | vgg-adain-relu4) and whether vgg-adain's VGG pool runs at all four
  // grid phases (the fast recipe's StyleModel::decoder_phases).
  std::string ckpt, profile = "fast", style_decoder = "stage2";
  bool decoder_phases = false;
  bool content_skip = false;  // stage 3: the content skip beside DST (the fast recipe's)
  int stage = 2, size = 256;
  // bench render only: the scene (default: the checkpoint's), held-out views to render, training steps to
  // time, and the early-termination thresholds to compare (empty: the default only).
  std::string scene;
  int views = 3, steps = 10;
  std::vector<float> erts;
};

int bench_gemm(const BenchOptions& opt);  // bench/bench_gemm.cpp
int bench_conv(const BenchOptions& opt);  // bench/bench_conv.cpp
int bench_ops(const BenchOptions& opt);   // bench/bench_ops.cpp: every NN op's perf mode (GB/s or GFLOP/s)
int bench_patch(const BenchOptions& opt); // bench/bench_patch.cpp: one patch-training step, part by part
int bench_patch_style(const BenchOptions& opt);  // bench/bench_patch_style.cpp: one stage-3 step, part by part
int bench_dst(const BenchOptions& opt);
int bench_decoder_step(const BenchOptions& opt);  // bench/bench_decoder_step.cpp: torch_step.py's work, s/step
int bench_render(const BenchOptions& opt);  // bench/bench_render.cpp: rays/s of rendering and training   // bench/bench_dst.cpp: deferred vs per-point style transformation

}  // namespace stylerf::bench
