// GEMM entry points: engine choice, CLBlast (defaults or tuned parameters) and the own kernel
// (host/gemm_own.cpp).
#include "host/gemm.hpp"

#include <clblast.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <iostream>
#include <limits>
#include <map>
#include <optional>
#include <unordered_map>

#include "host/error.hpp"
#include "host/launch.hpp"
#include "host/runtime.hpp"
#include "host/tensor.hpp"

namespace stylerf::host {
namespace {

GemmEngine g_default = GemmEngine::Auto;
std::optional<DeviceTuning> g_tuning_override;

using ParamSet = std::unordered_map<std::string, size_t>;

// Under profiling (STYLERF_PROFILE=1), the time of a whole CLBlast routine (its pad and transpose copies
// too, which the event CLBlast hands back does not cover), with the queue drained before and after. Named
// by shape, so the report shows which GEMMs of a step cost what.
class ClblastTimer {
 public:
  ClblastTimer(const char* what, Trans ta, Trans tb, int M, int N, int K) : rt_(Runtime::instance()) {
    if (!rt_.profiling()) return;
    name_ = std::string(what) + " " + std::to_string(M) + "x" + std::to_string(N) + "x" + std::to_string(K) +
            (ta == Trans::Yes ? " At" : "") + (tb == Trans::Yes ? " Bt" : "");
    rt_.finish();
    start_ = std::chrono::steady_clock::now();
  }
  ~ClblastTimer() {
    if (name_.empty()) return;
    try {
      rt_.finish();
      rt_.record_host(name_, std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start_).count());
    } catch (...) {  // a destructor must not throw; the GEMM's own error, if any, is already on its way
    }
  }

 private:
  Runtime& rt_;
  std::string name_;
  std::chrono::steady_clock::time_point start_;
};

// CLBlast's parameter sets for the runtime's device: its built-in defaults and our tuned values, both
// complete (OverrideParameters rejects a partial set), and which of the two is applied right now.
struct ClblastState {
  bool prepared = false;
  std::map<std::string, ParamSet> defaults, tuned;
  bool tuned_applied = false;  // nothing overridden yet means CLBlast's defaults are in effect
  std::string status;
};

ClblastState& clblast_state() {
  static ClblastState p;
  return p;
}

std::string join_names(const std::map<std::string, ParamSet>& m) {
  std::string s;
  for (const auto& kv : m) s += (s.empty() ? "" : ", ") + kv.first;
  return s;
}

// CLBlast builds its programs itself, without the -cl-denorms-are-zero that every program of ours gets
// (host/runtime.cpp); its CLBLAST_BUILD_OPTIONS variable adds it, so every engine keeps the numerical
// contract (docs/design.md: exact down to FLT_MIN, 0 below). Set before CLBlast's first build, kept where
// the caller already asks for it.
void clblast_flush_denormals() {
  constexpr const char* kFlush = "-cl-denorms-are-zero";
  const char* env = std::getenv("CLBLAST_BUILD_OPTIONS");
  const std::string options = env ? env : "";
  if (options.find(kFlush) != std::string::npos) return;
  // CLBlast joins its options without separators (so "-cl-std=..." would follow ours directly): end with a space.
  const std::string with_flush = options + " " + kFlush + " ";
  setenv("CLBLAST_BUILD_OPTIONS", with_flush.c_str(), 1);
}

void prepare_clblast_params() {
  ClblastState& cp = clblast_state();
  if (cp.prepared) return;
  cp.prepared = true;
  clblast_flush_denormals();
  const DeviceInfo& dev = Runtime::instance().device();
  const DeviceTuning* t = current_device_tuning();
  if (!t || t->clblast.empty()) {
    cp.status = "no CLBlast entry for '" + dev.name + "' in the tuning database: clblast-tuned runs CLBlast's defaults";
    return;
  }
  std::string problems;
  for (const auto& [kernel, params] : t->clblast) {
    ParamSet def;
    // Read before our first override, so these are CLBlast's own values for this device.
    auto st = clblast::RetrieveParameters(dev.id, kernel, clblast::Precision::kSingle, def);
    if (st != clblast::StatusCode::kSuccess) {
      problems += " " + kernel + ": CLBlast does not know this kernel family (" + std::to_string(int(st)) + ");";
      continue;
    }
    ParamSet full = def;
    std::string unknown;
    for (const auto& [name, value] : params) {
      if (def.count(name)) full[name] = value;
      else unknown += " " + name;
    }
    if (!unknown.empty()) {
      problems += " " + kernel + ": unknown parameters" + unknown + ";";
      continue;
    }
    cp.defaults[kernel] = def;
    cp.tuned[kernel] = full;
  }
  cp.status = cp.tuned.empty() ? "tuning database entry for '" + dev.name + "' is unusable:" + problems
                               : "tuning database (" + join_names(cp.tuned) + ")";
  if (!problems.empty()) {
    std::cerr << "stylerf: CLBlast tuning for '" << dev.name << "' partly skipped:" << problems << "\n";
    if (!cp.tuned.empty()) cp.status += "; skipped:" + problems;
  }
}

// Makes CLBlast use the tuned (or default) parameter sets from now on.
void apply_clblast_params(bool tuned) {
  prepare_clblast_params();
  ClblastState& cp = clblast_state();
  if (cp.tuned_applied == tuned || cp.tuned.empty()) return;
  const DeviceInfo& dev = Runtime::instance().device();
  for (const auto& [kernel, params] : tuned ? cp.tuned : cp.defaults) {
    auto st = clblast::OverrideParameters(dev.id, kernel, clblast::Precision::kSingle, params);
    if (st != clblast::StatusCode::kSuccess)
      throw Error("clblast::OverrideParameters(" + kernel + ") failed with status " + std::to_string(int(st)));
  }
  cp.tuned_applied = tuned;
}

GemmEngine engine_from_environment_or_db() {
  if (const char* env = std::getenv("STYLERF_GEMM_ENGINE"); env && *env) {
    try {
      GemmEngine e = parse_gemm_engine(env);
      if (e != GemmEngine::Auto) return e;
    } catch (const Error& err) {
      throw Error(std::string("STYLERF_GEMM_ENGINE: ") + err.what());
    }
  }
  // On a CPU device the host's BLAS works on the very memory the kernels use, and runs the decoder's
  // GEMMs about twice as fast as the best OpenCL kernel there (bench gemm); it comes before any
  // recommendation among the OpenCL engines.
  if (host_blas_usable()) return GemmEngine::HostBlas;
  if (const DeviceTuning* t = current_device_tuning(); t && !t->recommended_engine.empty()) {
    GemmEngine e = parse_gemm_engine(t->recommended_engine);
    // A database written by a build with a CBLAS may recommend host-blas to one without: the best
    // OpenCL engine on CPUs is our own kernel.
    if (e == GemmEngine::HostBlas) return GemmEngine::Own;
    if (e != GemmEngine::Auto) return e;
  }
  // Without a recommendation: CLBlast ships tunings for common GPUs but none for CPU drivers, where
  // our register-tiled kernel is the better default.
  return Runtime::instance().device().type & CL_DEVICE_TYPE_CPU ? GemmEngine::Own : GemmEngine::ClblastTuned;
}

void clblast_gemm(Trans ta, Trans tb, int M, int N, int K, float alpha, cl_mem A, size_t a_offset, int lda, cl_mem B,
                  size_t b_offset, int ldb, float beta, cl_mem C, size_t c_offset, int ldc, bool tuned) {
  apply_clblast_params(tuned);
  Runtime& rt = Runtime::instance();
  const ClblastTimer timer("clblast gemm", ta, tb, M, N, K);
  auto st = clblast::Gemm<float>(clblast::Layout::kRowMajor,
                                 ta == Trans::Yes ? clblast::Transpose::kYes : clblast::Transpose::kNo,
                                 tb == Trans::Yes ? clblast::Transpose::kYes : clblast::Transpose::kNo, M, N, K, alpha,
                                 A, a_offset, lda, B, b_offset, ldb, beta, C, c_offset, ldc, rt.queue_ptr(), nullptr);
  if (st != clblast::StatusCode::kSuccess)
    throw Error("clblast::Gemm failed (" + std::to_string(static_cast<int>(st)) + ") for M=" + std::to_string(M) +
                " N=" + std::to_string(N) + " K=" + std::to_string(K));
}

void clblast_gemm_batched(Trans ta, Trans tb, int M, int N, int K, float alpha, cl_mem A, size_t a_offset, int lda,
                          size_t a_stride, cl_mem B, size_t b_offset, int ldb, size_t b_stride, float beta, cl_mem C,
                          size_t c_offset, int ldc, size_t c_stride, int batch, bool tuned) {
  apply_clblast_params(tuned);
  Runtime& rt = Runtime::instance();
  const ClblastTimer timer(("clblast batched x" + std::to_string(batch)).c_str(), ta, tb, M, N, K);
  const auto tr = [](Trans t) { return t == Trans::Yes ? clblast::Transpose::kYes : clblast::Transpose::kNo; };
  auto st = clblast::GemmStridedBatched<float>(clblast::Layout::kRowMajor, tr(ta), tr(tb), M, N, K, alpha, A, a_offset,
                                               lda, a_stride, B, b_offset, ldb, b_stride, beta, C, c_offset, ldc,
                                               c_stride, batch, rt.queue_ptr(), nullptr);
  if (st != clblast::StatusCode::kSuccess)
    throw Error("clblast::GemmStridedBatched failed (" + std::to_string(static_cast<int>(st)) + ") for M=" +
                std::to_string(M) + " N=" + std::to_string(N) + " K=" + std::to_string(K) + " batch " +
                std::to_string(batch));
}

// ---- split-K ----------------------------------------------------------------------------------------
// CLBlast spreads a GEMM over C's tiles only. A weight gradient over millions of rows (SICT's q/k/v:
// 256 x 96 outputs, K = 3M points) has a handful of 64 x 64 tiles, so it ran on ~8 of an H100's 132
// compute units. Such a GEMM runs as `parts` chunks of K, multiplied by one GemmStridedBatched into a
// scratch [parts, M, N] and added in order by kernels/gemm_split.cl.
int g_split_k = 0;  // 0: auto; 1: never; >= 2: always this many chunks (tests, benchmarks)

int split_k_setting() {
  if (g_split_k != 0) return g_split_k;
  static const int from_env = [] {
    const char* env = std::getenv("STYLERF_GEMM_SPLIT_K");
    if (!env || !*env || std::string(env) == "auto") return 0;
    char* end = nullptr;
    const long v = std::strtol(env, &end, 10);
    if (*end != '\0' || v < 1 || v > 4096)
      throw Error(std::string("STYLERF_GEMM_SPLIT_K: expected auto or a number of chunks 1..4096, got '") + env + "'");
    return int(v);
  }();
  return from_env;
}

void clblast_gemm_split(Trans ta, Trans tb, int M, int N, int K, float alpha, cl_mem A, size_t a_offset, int lda,
                        cl_mem B, size_t b_offset, int ldb, float beta, cl_mem C, size_t c_offset, int ldc, bool tuned,
                        int parts) {
  // `parts` chunks of kc = floor(K / parts) in one batched call, and a tail of fewer than `parts` rows: a
  // ceil-sized chunk left a tail of up to a whole chunk, run as one GEMM on a handful of tiles (7 ms of a
  // 19 ms covariance over 3.1M rows on an H200).
  const int kc = K / parts;
  const int full = parts, tail = K - full * kc, slots = full + (tail > 0 ? 1 : 0);
  // Moving k by kc: columns of a stored row for an untransposed A (rows of B), whole rows otherwise.
  const size_t a_step = ta == Trans::No ? size_t(kc) : size_t(kc) * size_t(lda);
  const size_t b_step = tb == Trans::No ? size_t(kc) * size_t(ldb) : size_t(kc);
  const size_t mn = size_t(M) * size_t(N);
  // Zeroed: CLBlast computes beta * C even for beta = 0, and pooled memory may hold NaN.
  const ClblastTimer timer(("clblast split-K x" + std::to_string(slots)).c_str(), ta, tb, M, N, K);
  Tensor partial = Tensor::zeros({int64_t(slots) * int64_t(mn)}, "gemm split-K partial products");
  apply_clblast_params(tuned);
  Runtime& rt = Runtime::instance();
  const auto tr = [](Trans t) { return t == Trans::Yes ? clblast::Transpose::kYes : clblast::Transpose::kNo; };
  auto st = clblast::GemmStridedBatched<float>(clblast::Layout::kRowMajor, tr(ta), tr(tb), M, N, kc, 1.0f, A, a_offset,
                                               lda, a_step, B, b_offset, ldb, b_step, 0.0f, partial.mem(), 0, N, mn,
                                               full, rt.queue_ptr(), nullptr);
  if (st != clblast::StatusCode::kSuccess)
    throw Error("clblast::GemmStridedBatched failed (" + std::to_string(static_cast<int>(st)) + ") for split-K M=" +
                std::to_string(M) + " N=" + std::to_string(N) + " K=" + std::to_string(K) + " in " +
                std::to_string(full) + " chunks of " + std::to_string(kc));
  if (tail > 0)
    clblast_gemm(ta, tb, M, N, tail, 1.0f, A, a_offset + size_t(full) * a_step, lda, B,
                 b_offset + size_t(full) * b_step, ldb, 0.0f, partial.mem(), size_t(full) * mn, N, tuned);
  if (c_offset > size_t(std::numeric_limits<int>::max())) throw Error("gemm split-K: C offset exceeds int range");
  launch("gemm_split", "gemm_sum_chunks", {size_t(N), size_t(M)}, partial, slots, M, N, alpha, beta, C, int(c_offset),
         ldc);
}

}  // namespace

void set_gemm_split_k(int parts) {
  if (parts < 0 || parts > 4096)
    throw Error("set_gemm_split_k: parts must be 0 (auto) or 1..4096, got " + std::to_string(parts));
  g_split_k = parts;
}

int gemm_split_k_parts(int M, int N, int K, int batch) {
  const int setting = split_k_setting();
  if (setting >= 1) return std::max(1, std::min(setting, K));
  const DeviceInfo& d = Runtime::instance().device();
  if (d.type & CL_DEVICE_TYPE_CPU) return 1;  // a CPU has few compute units; CPU GEMMs use host-blas anyway
  // A batch runs as one call, its GEMMs side by side. Splitting it would take one call per GEMM: on an H200
  // Winograd's 36 filter gradients of 64 x 64 x 4096 took 5.1 ms that way, ~140 us a call.
  if (batch > 1) return 1;
  const int64_t tiles = int64_t((M + 63) / 64) * int64_t((N + 63) / 64);
  const int64_t cus = std::max<int64_t>(1, d.compute_units);
  if (tiles >= cus) return 1;
  // About two work-groups' worth of tiles per compute unit, each chunk at least 2048 long.
  const int64_t parts = std::min<int64_t>((2 * cus + tiles - 1) / tiles, K / 2048);
  return parts >= 2 ? int(std::min<int64_t>(parts, 4096)) : 1;
}

const char* gemm_engine_name(GemmEngine e) {
  switch (e) {
    case GemmEngine::Auto: return "auto";
    case GemmEngine::ClblastDefault: return "clblast-default";
    case GemmEngine::ClblastTuned: return "clblast-tuned";
    case GemmEngine::Own: return "own";
    case GemmEngine::HostBlas: return "host-blas";
  }
  return "?";
}

GemmEngine parse_gemm_engine(const std::string& name) {
  for (GemmEngine e : {GemmEngine::Auto, GemmEngine::ClblastDefault, GemmEngine::ClblastTuned, GemmEngine::Own,
                       GemmEngine::HostBlas})
    if (name == gemm_engine_name(e)) return e;
  throw Error("unknown GEMM engine '" + name + "' (auto, clblast-default, clblast-tuned, own, host-blas)");
}

void set_default_gemm_engine(GemmEngine e) { g_default = e; }

GemmEngine resolve_gemm_engine(GemmEngine e) {
  if (e != GemmEngine::Auto) return e;
  if (g_default != GemmEngine::Auto) return g_default;
  static const GemmEngine chosen = engine_from_environment_or_db();
  return chosen;
}

OwnGemmParams own_gemm_params() {
  if (const DeviceTuning* t = current_device_tuning(); t && t->own_gemm) return *t->own_gemm;
  return OwnGemmParams{};
}

const DeviceTuning* current_device_tuning() {
  return g_tuning_override ? &*g_tuning_override : active_device_tuning();
}

void use_device_tuning(const DeviceTuning& t) {
  // Put CLBlast back on its defaults first: the next prepare reads them again with RetrieveParameters.
  apply_clblast_params(false);
  clblast_state() = ClblastState{};
  g_tuning_override = t;
}

std::string clblast_tuning_status() {
  prepare_clblast_params();
  return clblast_state().status;
}

void gemm_strided_batched(Trans ta, Trans tb, int M, int N, int K, float alpha, cl_mem A, size_t a_offset, int lda,
                          size_t a_stride, cl_mem B, size_t b_offset, int ldb, size_t b_stride, float beta, cl_mem C,
                          size_t c_offset, int ldc, size_t c_stride, int batch, GemmEngine engine) {
  if (M < 0 || N < 0 || K < 0 || batch < 0)
    throw Error("gemm: negative size M=" + std::to_string(M) + " N=" + std::to_string(N) + " K=" + std::to_string(K) +
                " batch=" + std::to_string(batch));
  // Row-major leading dimensions must cover a stored row; CLBlast checks this too, the own kernel relies on it.
  const int a_cols = ta == Trans::No ? K : M, b_cols = tb == Trans::No ? N : K;
  if (lda < std::max(1, a_cols) || ldb < std::max(1, b_cols) || ldc < std::max(1, N))
    throw Error("gemm: leading dimension too small (lda=" + std::to_string(lda) + " ldb=" + std::to_string(ldb) +
                " ldc=" + std::to_string(ldc) + " for M=" + std::to_string(M) + " N=" + std::to_string(N) +
                " K=" + std::to_string(K) + ")");
  if (M == 0 || N == 0 || batch == 0) return;
  const GemmEngine e = resolve_gemm_engine(engine);
  if (e == GemmEngine::HostBlas) {  // CBLAS gives K = 0 its BLAS meaning, C = beta * C
    host_blas_gemm_batched(ta, tb, M, N, K, alpha, A, a_offset, lda, a_stride, B, b_offset, ldb, b_stride, beta, C,
                           c_offset, ldc, c_stride, batch);
    return;
  }
  const bool clblast = e == GemmEngine::ClblastDefault || e == GemmEngine::ClblastTuned;
  if (clblast && batch > 1 && K > 0 && gemm_split_k_parts(M, N, K, batch) < 2) {
    // One CLBlast call for the whole batch: Winograd's 36 products per conv were 36 calls, each with
    // its host overhead and its own pad copies.
    clblast_gemm_batched(ta, tb, M, N, K, alpha, A, a_offset, lda, a_stride, B, b_offset, ldb, b_stride, beta, C,
                         c_offset, ldc, c_stride, batch, e != GemmEngine::ClblastDefault);
    return;
  }
  for (int i = 0; i < batch; ++i) {
    const size_t ao = a_offset + i * a_stride, bo = b_offset + i * b_stride, co = c_offset + i * c_stride;
    if (K == 0 || e == GemmEngine::Own) {
      // K = 0 means C = beta * C (BLAS semantics). CLBlast rejects it, so every engine takes the own kernel's path.
      gemm_own_with(own_gemm_params(), ta, tb, M, N, K, alpha, A, ao, lda, B, bo, ldb, beta, C, co, ldc);
    } else if (const int parts = gemm_split_k_parts(M, N, K); parts >= 2) {
      clblast_gemm_split(ta, tb, M, N, K, alpha, A, ao, lda, B, bo, ldb, beta, C, co, ldc,
                         e != GemmEngine::ClblastDefault, parts);
    } else {
      clblast_gemm(ta, tb, M, N, K, alpha, A, ao, lda, B, bo, ldb, beta, C, co, ldc, e != GemmEngine::ClblastDefault);
    }
  }
}

void gemm(Trans ta, Trans tb, int M, int N, int K, float alpha, cl_mem A, size_t a_offset, int lda, cl_mem B,
          size_t b_offset, int ldb, float beta, cl_mem C, size_t c_offset, int ldc, GemmEngine engine) {
  gemm_strided_batched(ta, tb, M, N, K, alpha, A, a_offset, lda, 0, B, b_offset, ldb, 0, beta, C, c_offset, ldc, 0, 1,
                       engine);
}

void matmul(const Tensor& A, Trans ta, const Tensor& B, Trans tb, Tensor& C, float alpha, float beta,
            GemmEngine engine) {
  if (A.ndim() != 2 || B.ndim() != 2 || C.ndim() != 2)
    throw Error("matmul: expects 2-D tensors, got " + shape_str(A.shape()) + ", " + shape_str(B.shape()) + ", " +
                shape_str(C.shape()));
  expect_dtype(A, DType::F32, "matmul", "A");
  expect_dtype(B, DType::F32, "matmul", "B");
  expect_dtype(C, DType::F32, "matmul", "C");
  int M = static_cast<int>(ta == Trans::No ? A.dim(0) : A.dim(1));
  int K = static_cast<int>(ta == Trans::No ? A.dim(1) : A.dim(0));
  int Kb = static_cast<int>(tb == Trans::No ? B.dim(0) : B.dim(1));
  int N = static_cast<int>(tb == Trans::No ? B.dim(1) : B.dim(0));
  if (K != Kb || C.dim(0) != M || C.dim(1) != N)
    throw Error("matmul: shapes do not agree: op(A) " + std::to_string(M) + "x" + std::to_string(K) + ", op(B) " +
                std::to_string(Kb) + "x" + std::to_string(N) + ", C " + shape_str(C.shape()));
  gemm(ta, tb, M, N, K, alpha, A.mem(), 0, static_cast<int>(A.dim(1)), B.mem(), 0, static_cast<int>(B.dim(1)), beta,
       C.mem(), 0, static_cast<int>(C.dim(1)), engine);
}

}  // namespace stylerf::host
