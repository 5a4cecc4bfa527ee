// `stylerf bench gemm`: GFLOP/s of every GEMM engine and of OpenBLAS at 1024^3 and at the decoder's
// im2col shapes for a 256x256 patch, all measured in the same run so the ratios are comparable on a
// shared, noisy machine. Each engine's result is checked against OpenBLAS (normwise relative error).
//
// Timing: one warm-up call (kernel compilation, CLBlast program build), then opt.repeats timed calls,
// stopping early once 20 s are spent on one engine and shape; the best (minimum) time is reported, as
// the least noise-affected estimate of what the engine can do.
//
// CLBlast defaults vs tuned: host/gemm.cpp captures CLBlast's built-in parameters before the first
// override and re-applies whichever set a call's engine needs, so "clblast-default" really runs
// CLBlast's defaults even though "clblast-tuned" ran before it in the same process.
//
// Development filters (environment): STYLERF_BENCH_GEMM_ENGINES=own,openblas (subset of engines) and
// STYLERF_BENCH_GEMM_SHAPES=fwd256,dW256 (subset of shape names).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "bench/bench.hpp"
#include "host/files.hpp"
#include "host/gemm.hpp"
#include "host/runtime.hpp"
#include "host/tensor.hpp"

#ifdef STYLERF_HAVE_OPENBLAS
#include <cblas.h>
extern "C" void openblas_set_num_threads(int num_threads);
#endif

namespace stylerf::bench {
namespace {

using host::GemmEngine;
using host::Trans;

struct Shape {
  std::string name, role;
  Trans ta, tb;
  int M, N, K;
};

// The decoder's convs at a 256x256 patch (HW = 65536), im2col + GEMM:
//   forward out[Cout,HW] = W[Cout,Cin*9] col[Cin*9,HW]; dX: col_grad = W^T dY; dW = dY col^T.
std::vector<Shape> shapes(bool quick) {
  const int hw = quick ? 64 * 64 : 256 * 256;
  const int sq = quick ? 512 : 1024;
  return {
      {"square", "1024^3 reference", Trans::No, Trans::No, sq, sq, sq},
      {"fwd256", "conv 256->256 forward", Trans::No, Trans::No, 256, hw, 2304},
      {"fwd128", "conv 128->128 forward", Trans::No, Trans::No, 128, hw, 1152},
      {"fwd64", "conv 64->64 forward", Trans::No, Trans::No, 64, hw, 576},
      {"fwd3", "conv 64->3 forward", Trans::No, Trans::No, 3, hw, 576},
      {"dX256", "conv 256->256 dX (W^T dY)", Trans::Yes, Trans::No, 2304, hw, 256},
      {"dW256", "conv 256->256 dW (dY col^T)", Trans::No, Trans::Yes, 256, 2304, hw},
  };
}

std::vector<std::string> split_list(const char* env) {
  std::vector<std::string> out;
  if (!env) return out;
  std::stringstream s(env);
  std::string item;
  while (std::getline(s, item, ','))
    if (!item.empty()) out.push_back(item);
  return out;
}

bool selected(const std::vector<std::string>& list, const std::string& name) {
  return list.empty() || std::find(list.begin(), list.end(), name) != list.end();
}

// Cheap deterministic fill in [-1, 1): the buffers reach 600 MB, where a normal distribution is slow.
void fill(std::vector<float>& v, uint32_t seed) {
  uint32_t x = seed * 2654435761u + 1;
  for (auto& e : v) {
    x = x * 1664525u + 1013904223u;
    e = static_cast<float>(x >> 8) * (2.0f / 16777216.0f) - 1.0f;
  }
}

double rel_error(const std::vector<float>& got, const std::vector<float>& ref) {
  double num = 0.0, den = 0.0;
  for (size_t i = 0; i < got.size(); ++i) {
    const double d = static_cast<double>(got[i]) - ref[i];
    num = std::max(num, std::fabs(d));
    den = std::max(den, std::fabs(static_cast<double>(ref[i])));
    if (!std::isfinite(got[i])) return INFINITY;
  }
  return den > 0 ? num / den : num;
}

// Best time in seconds of fn() over the timed repetitions (after one warm-up).
template <class F>
double best_time(const BenchOptions& opt, F&& fn) {
  using clock = std::chrono::steady_clock;
  fn();
  double best = 1e30, spent = 0.0;
  for (int r = 0; r < opt.repeats; ++r) {
    auto t0 = clock::now();
    fn();
    const double s = std::chrono::duration<double>(clock::now() - t0).count();
    best = std::min(best, s);
    spent += s;
    if (spent > 20.0) break;
  }
  return best;
}

}  // namespace

int bench_gemm(const BenchOptions& opt) {
  host::Runtime& rt = host::Runtime::instance();
  const auto engine_filter = split_list(std::getenv("STYLERF_BENCH_GEMM_ENGINES"));
  const auto shape_filter = split_list(std::getenv("STYLERF_BENCH_GEMM_SHAPES"));
  const GemmEngine auto_engine = host::resolve_gemm_engine(GemmEngine::Auto);
  const std::string auto_name = host::gemm_engine_name(auto_engine);
  const int threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
#ifdef STYLERF_HAVE_OPENBLAS
  openblas_set_num_threads(threads);
#endif

  std::cout << "device: " << rt.device().describe() << "\n"
            << "auto engine: " << auto_name << "; own kernel: " << host::own_gemm_params().describe()
            << "\nclblast-tuned: " << host::clblast_tuning_status() << "\n"
            << "OpenBLAS threads: " << threads << "; time = best of " << opt.repeats
            << " after a warm-up (20 s cap per engine and shape); all ratios from this one run\n\n";

  // host-blas is the library's engine over the same OpenBLAS (single-threaded pieces on its own threads,
  // through mapped buffers); "openblas" is OpenBLAS called directly on host arrays with its own pool.
  std::vector<std::string> engines = {"openblas", "own", "clblast-tuned", "clblast-default"};
  if (host::host_blas_usable()) engines.push_back("host-blas");
  nlohmann::json jshapes = nlohmann::json::array();
  double worst_ratio = 1e30;
  double worst_opencl_ratio = 1e30;  // best OpenCL engine per shape: the path every non-CPU device runs
  bool errors_ok = true;

  std::cout << std::left << std::setw(8) << "shape" << std::setw(24) << "M x N x K (op)" << std::right;
  for (const auto& e : engines) std::cout << std::setw(17) << e;
  std::cout << std::setw(14) << "auto/OpenBLAS" << std::endl;

  for (const Shape& s : shapes(opt.quick)) {
    if (!selected(shape_filter, s.name)) continue;
    const bool ta = s.ta == Trans::Yes, tb = s.tb == Trans::Yes;
    const int lda = ta ? s.M : s.K, ldb = tb ? s.K : s.N, ldc = s.N;
    std::vector<float> ha(static_cast<size_t>(s.M) * s.K), hb(static_cast<size_t>(s.K) * s.N),
        ref(static_cast<size_t>(s.M) * s.N, 0.0f);
    fill(ha, 1);
    fill(hb, 2);
    host::Tensor A = host::Tensor::from_host(ha, {static_cast<int64_t>(ha.size())}, "bench A");
    host::Tensor B = host::Tensor::from_host(hb, {static_cast<int64_t>(hb.size())}, "bench B");
    host::Tensor C = host::Tensor::zeros({static_cast<int64_t>(ref.size())}, "bench C");
    const double flops = 2.0 * s.M * s.N * static_cast<double>(s.K);

    std::map<std::string, double> gflops, err;
    bool have_ref = false;
#ifdef STYLERF_HAVE_OPENBLAS
    {
      openblas_set_num_threads(threads);  // the host-blas engine sets 1 for its own calls
      auto run = [&] {
        cblas_sgemm(CblasRowMajor, ta ? CblasTrans : CblasNoTrans, tb ? CblasTrans : CblasNoTrans, s.M, s.N, s.K, 1.0f,
                    ha.data(), lda, hb.data(), ldb, 0.0f, ref.data(), ldc);
      };
      // Always run: its result is the reference the engines are checked against.
      gflops["openblas"] = flops / best_time(opt, run) * 1e-9;
      have_ref = true;
    }
#endif
    for (const auto& e : engines) {
      if (e == "openblas" || !selected(engine_filter, e)) continue;
      const GemmEngine ge = host::parse_gemm_engine(e);
      auto run = [&] {
        host::gemm(s.ta, s.tb, s.M, s.N, s.K, 1.0f, A.mem(), 0, lda, B.mem(), 0, ldb, 0.0f, C.mem(), 0, ldc, ge);
        rt.finish();
      };
      C.zero();
      gflops[e] = flops / best_time(opt, run) * 1e-9;
      if (have_ref) {
        err[e] = rel_error(C.to_host(), ref);
        if (!(err[e] < 1e-4)) errors_ok = false;  // float32 with K up to 65536: normwise ~1e-6 expected
      }
    }

    std::ostringstream dims;
    dims << s.M << "x" << s.N << "x" << s.K << " (" << (ta ? "T" : "N") << (tb ? "T" : "N") << ")";
    std::cout << std::left << std::setw(8) << s.name << std::setw(24) << dims.str() << std::right << std::fixed
              << std::setprecision(1);
    for (const auto& e : engines) {
      if (gflops.count(e)) std::cout << std::setw(17) << gflops[e];
      else std::cout << std::setw(17) << "-";
    }
    nlohmann::json js = {{"name", s.name}, {"role", s.role}, {"trans_a", ta}, {"trans_b", tb},
                         {"M", s.M},       {"N", s.N},       {"K", s.K}};
    js["gflops"] = gflops;
    js["max_rel_error_vs_openblas"] = err;
    nlohmann::json ratios = nlohmann::json::object();
    if (gflops.count("openblas"))
      for (const auto& [e, g] : gflops)
        if (e != "openblas") ratios[e] = g / gflops["openblas"];
    js["ratio_vs_openblas"] = ratios;
    if (gflops.count("openblas")) {
      double best_cl = 0.0;
      for (const char* e : {"own", "clblast-tuned", "clblast-default"})
        if (gflops.count(e)) best_cl = std::max(best_cl, gflops[e]);
      if (best_cl > 0.0) worst_opencl_ratio = std::min(worst_opencl_ratio, best_cl / gflops["openblas"]);
    }
    if (gflops.count("openblas") && gflops.count(auto_name)) {
      const double r = gflops[auto_name] / gflops["openblas"];
      js["ratio_tuned_vs_openblas"] = r;
      worst_ratio = std::min(worst_ratio, r);
      std::cout << std::setw(13) << std::setprecision(1) << 100.0 * r << "%";
    }
    std::cout << "\n        max rel error vs OpenBLAS:";
    for (const auto& [e, v] : err) std::cout << " " << e << " " << std::scientific << std::setprecision(1) << v;
    std::cout << std::fixed << std::endl;  // flush: each shape takes a while at full size
    jshapes.push_back(js);
  }

  // The least share of OpenBLAS's speed the tuned engine must reach on every shape (the JSON keeps the
  // key names floor_ratio / floor_met that recorded runs use).
  const double minimum_ratio = 0.25;
  const bool have_ratio = worst_ratio < 1e29;
  std::cout << "\nengine Auto uses: " << auto_name;
  if (have_ratio)
    std::cout << "; worst ratio vs OpenBLAS " << std::setprecision(1) << 100.0 * worst_ratio << "% (minimum "
              << 100.0 * minimum_ratio << "%, goal 50%): "
              << (worst_ratio >= minimum_ratio ? "minimum met" : "BELOW THE MINIMUM");
  if (worst_opencl_ratio < 1e29)
    std::cout << "\nbest OpenCL engine (what a GPU runs): worst ratio vs OpenBLAS " << std::setprecision(1)
              << 100.0 * worst_opencl_ratio << "%";
  std::cout << "\n" << (errors_ok ? "all results agree with OpenBLAS (normwise rel error < 1e-4)"
                                   : "SOME RESULTS DISAGREE WITH OpenBLAS")
            << "\n";

  if (!opt.json_path.empty()) {
    nlohmann::json j = {{"bench", "gemm"},
                        {"device", rt.device().name},
                        {"quick", opt.quick},
                        {"repeats", opt.repeats},
                        {"timing", "best of repeats after one warm-up, 20 s cap per engine and shape"},
                        {"openblas_threads", threads},
                        {"auto_engine", auto_name},
                        {"own_gemm", host::own_gemm_params().describe()},
                        {"clblast_tuning", host::clblast_tuning_status()},
                        {"floor_ratio", minimum_ratio},
                        {"shapes", jshapes}};
    if (have_ratio) {
      j["worst_ratio_tuned_vs_openblas"] = worst_ratio;
      j["floor_met"] = worst_ratio >= minimum_ratio;
    }
    if (worst_opencl_ratio < 1e29) j["worst_ratio_best_opencl_vs_openblas"] = worst_opencl_ratio;
    j["results_agree"] = errors_ok;
    host::write_file_atomic(opt.json_path, j.dump(2) + "\n");
    std::cout << "wrote " << opt.json_path << "\n";
  }
  return errors_ok ? 0 : 1;
}

}  // namespace stylerf::bench
