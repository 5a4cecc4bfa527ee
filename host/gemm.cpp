// Minimal CLBlast-backed GEMM; tuned parameters and the own-kernel engine are added by the GEMM work.
#include "host/gemm.hpp"

#include <clblast.h>

#include "host/error.hpp"
#include "host/runtime.hpp"

namespace stylerf::host {
namespace {
GemmEngine g_default = GemmEngine::Auto;
}

const char* gemm_engine_name(GemmEngine e) {
  switch (e) {
    case GemmEngine::Auto: return "auto";
    case GemmEngine::ClblastDefault: return "clblast-default";
    case GemmEngine::ClblastTuned: return "clblast-tuned";
    case GemmEngine::Own: return "own";
  }
  return "?";
}

GemmEngine parse_gemm_engine(const std::string& name) {
  for (GemmEngine e : {GemmEngine::Auto, GemmEngine::ClblastDefault, GemmEngine::ClblastTuned, GemmEngine::Own})
    if (name == gemm_engine_name(e)) return e;
  throw Error("unknown GEMM engine '" + name + "' (auto, clblast-default, clblast-tuned, own)");
}

void set_default_gemm_engine(GemmEngine e) { g_default = e; }
GemmEngine default_gemm_engine() { return g_default; }

void gemm(Trans ta, Trans tb, int M, int N, int K, float alpha, cl_mem A, size_t a_offset, int lda, cl_mem B,
          size_t b_offset, int ldb, float beta, cl_mem C, size_t c_offset, int ldc, GemmEngine engine) {
  Runtime& rt = Runtime::instance();
  auto st = clblast::Gemm<float>(clblast::Layout::kRowMajor,
                                 ta == Trans::Yes ? clblast::Transpose::kYes : clblast::Transpose::kNo,
                                 tb == Trans::Yes ? clblast::Transpose::kYes : clblast::Transpose::kNo, M, N, K, alpha,
                                 A, a_offset, lda, B, b_offset, ldb, beta, C, c_offset, ldc, rt.queue_ptr(), nullptr);
  if (st != clblast::StatusCode::kSuccess)
    throw Error("clblast::Gemm failed (" + std::to_string(static_cast<int>(st)) + ") for M=" + std::to_string(M) +
                " N=" + std::to_string(N) + " K=" + std::to_string(K));
}

void matmul(const Tensor& A, Trans ta, const Tensor& B, Trans tb, Tensor& C, float alpha, float beta,
            GemmEngine engine) {
  if (A.ndim() != 2 || B.ndim() != 2 || C.ndim() != 2)
    throw Error("matmul: expects 2-D tensors, got " + shape_str(A.shape()) + ", " + shape_str(B.shape()) + ", " +
                shape_str(C.shape()));
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
