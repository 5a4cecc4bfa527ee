// Single-precision GEMM on the runtime's device, row-major:
//   C[M,N] = alpha * op(A)[M,K] * op(B)[K,N] + beta * C
// with op(X) = X or X^T, leading dimensions in elements and buffer offsets in elements.
//
// Engines: CLBlast with its built-in defaults, CLBlast with our per-device tuned parameters
// (tuning/clblast.json, applied once per process with clblast::OverrideParameters), our own
// register-tiled kernel (kernels/gemm.cl), and, on CPU devices only, the host's CBLAS over the mapped
// buffers (host/gemm_host_blas.cpp). `Auto` resolves, in order: set_default_gemm_engine(), the
// STYLERF_GEMM_ENGINE environment variable, host-blas where it can run (a CPU device and a build with a
// CBLAS), the tuning database's recommendation for the device, and finally `own` on CPU devices (CLBlast
// has no tuning for them) and tuned CLBlast elsewhere. A recommendation of host-blas that this build or
// device cannot run falls back to `own`.
//
// CLBlast's parameters are process-global per device. This module keeps CLBlast's built-in defaults
// (read with RetrieveParameters before anything is overridden) and re-applies whichever set a call's
// engine needs, so ClblastDefault really runs CLBlast's defaults even after tuned calls. CLBlast keys
// its compiled programs by the parameter values, so switching back and forth does not recompile.
#pragma once
#include <CL/cl.h>

#include <cstddef>
#include <string>

#include "host/tensor.hpp"
#include "host/tuning_db.hpp"

namespace stylerf::host {

enum class Trans { No, Yes };
enum class GemmEngine { Auto, ClblastDefault, ClblastTuned, Own, HostBlas };

const char* gemm_engine_name(GemmEngine e);
// "auto", "clblast-default", "clblast-tuned", "own", "host-blas"
GemmEngine parse_gemm_engine(const std::string& name);

// Engine used when a call passes GemmEngine::Auto (default Auto => device recommendation).
void set_default_gemm_engine(GemmEngine e);

void gemm(Trans ta, Trans tb, int M, int N, int K, float alpha, cl_mem A, size_t a_offset, int lda, cl_mem B,
          size_t b_offset, int ldb, float beta, cl_mem C, size_t c_offset, int ldc,
          GemmEngine engine = GemmEngine::Auto);

// The same GEMM on `batch` operand sets, the i-th at X_offset + i * X_stride elements of each buffer. The
// host-blas engine maps the buffers once for the whole batch; CLBlast runs it as one GemmStridedBatched (a batch
// it would split along K: one GEMM each); the own kernel enqueues one GEMM each.
void gemm_strided_batched(Trans ta, Trans tb, int M, int N, int K, float alpha, cl_mem A, size_t a_offset, int lda,
                          size_t a_stride, cl_mem B, size_t b_offset, int ldb, size_t b_stride, float beta, cl_mem C,
                          size_t c_offset, int ldc, size_t c_stride, int batch, GemmEngine engine = GemmEngine::Auto);

// Split-K for the CLBlast engines: a GEMM with fewer 64 x 64 tiles of C than the device has compute
// units and a long K (a weight gradient over millions of rows) runs as chunks of K in one batched GEMM,
// then a kernel adds the chunks in order (kernels/gemm_split.cl). Auto splits on non-CPU devices only, into
// about 2 * compute units / tiles chunks of at least 2048. set_gemm_split_k(P): 0 auto (the default; the
// STYLERF_GEMM_SPLIT_K variable, auto or a count, sets it for a process), 1 never, P >= 2 always P chunks
// (at most K). gemm_split_k_parts says what a CLBlast GEMM of that shape runs as here (1: unsplit); Auto
// never splits a batch (batch > 1), which runs as one GemmStridedBatched call.
void set_gemm_split_k(int parts);
int gemm_split_k_parts(int M, int N, int K, int batch = 1);

// host-blas: whether this build links a CBLAS, and whether it can run here (linked, and a CPU device).
bool host_blas_linked();
bool host_blas_usable();

// Tensor convenience: C = alpha * op(A) op(B) + beta * C on 2-D tensors (shapes checked).
void matmul(const Tensor& A, Trans ta, const Tensor& B, Trans tb, Tensor& C, float alpha = 1.0f, float beta = 0.0f,
            GemmEngine engine = GemmEngine::Auto);

// The engine a call with `e` runs (never Auto).
GemmEngine resolve_gemm_engine(GemmEngine e);

// Our own kernel with explicit tile parameters (tuning, benchmarks); gemm() uses own_gemm_params().
void gemm_own_with(const OwnGemmParams& params, Trans ta, Trans tb, int M, int N, int K, float alpha, cl_mem A,
                   size_t a_offset, int lda, cl_mem B, size_t b_offset, int ldb, float beta, cl_mem C,
                   size_t c_offset, int ldc);
// The host-blas engine itself (gemm_strided_batched() with engine HostBlas, minus the argument checks).
void host_blas_gemm_batched(Trans ta, Trans tb, int M, int N, int K, float alpha, cl_mem A, size_t a_offset, int lda,
                            size_t a_stride, cl_mem B, size_t b_offset, int ldb, size_t b_stride, float beta, cl_mem C,
                            size_t c_offset, int ldc, size_t c_stride, int batch);
// The own kernel's parameters for the runtime's device: the tuning database's, else built-in defaults.
OwnGemmParams own_gemm_params();

// Replaces, for this process, the tuning entry used for the runtime's device (CLBlast parameters and own
// kernel parameters); `stylerf tune` uses it to measure fresh tuner results before saving them.
void use_device_tuning(const DeviceTuning& t);
// The entry in use for the runtime's device: use_device_tuning()'s, else active_device_tuning().
const DeviceTuning* current_device_tuning();

// What the ClblastTuned engine applies for the runtime's device: "tuning database" or a reason it runs
// CLBlast's defaults instead ("no entry for device ..."). For reports.
std::string clblast_tuning_status();

}  // namespace stylerf::host
