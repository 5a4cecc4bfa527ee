// Single-precision GEMM on the runtime's device, row-major:
//   C[M,N] = alpha * op(A)[M,K] * op(B)[K,N] + beta * C
// with op(X) = X or X^T, leading dimensions in elements and buffer offsets in elements.
//
// Engines: CLBlast with its built-in defaults, CLBlast with our per-device tuned parameters
// (tuning/clblast.json, applied once per process with clblast::OverrideParameters), and our own
// register-tiled kernel (kernels/gemm.cl). `Auto` picks what the tuning database recommends for the
// device, falling back to tuned CLBlast.
#pragma once
#include <CL/cl.h>

#include <cstddef>
#include <string>

#include "host/tensor.hpp"

namespace stylerf::host {

enum class Trans { No, Yes };
enum class GemmEngine { Auto, ClblastDefault, ClblastTuned, Own };

const char* gemm_engine_name(GemmEngine e);
GemmEngine parse_gemm_engine(const std::string& name);  // "auto", "clblast-default", "clblast-tuned", "own"

// Engine used when a call passes GemmEngine::Auto (default Auto => device recommendation).
void set_default_gemm_engine(GemmEngine e);
GemmEngine default_gemm_engine();

void gemm(Trans ta, Trans tb, int M, int N, int K, float alpha, cl_mem A, size_t a_offset, int lda, cl_mem B,
          size_t b_offset, int ldb, float beta, cl_mem C, size_t c_offset, int ldc,
          GemmEngine engine = GemmEngine::Auto);

// Tensor convenience: C = alpha * op(A) op(B) + beta * C on 2-D tensors (shapes checked).
void matmul(const Tensor& A, Trans ta, const Tensor& B, Trans tb, Tensor& C, float alpha = 1.0f, float beta = 0.0f,
            GemmEngine engine = GemmEngine::Auto);

}  // namespace stylerf::host
