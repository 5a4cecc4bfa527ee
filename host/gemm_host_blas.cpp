// The host-BLAS GEMM engine: on CPU OpenCL devices (PoCL) a buffer's storage is ordinary host memory, so
// mapping it hands the host a pointer to the very bytes the kernels use, without a copy. The engine drains
// the queue (the blocking map waits for every earlier command), runs the host's CBLAS sgemm on the mapped
// pointers, and unmaps. Only CPU devices get it: on a GPU the map would copy over the bus.
//
// The library links a CBLAS (OpenBLAS) when CMake finds one (STYLERF_HAVE_HOST_BLAS); without it the
// engine reports itself unavailable and Auto never picks it.
#include <algorithm>
#include <chrono>
#include <string>
#include <thread>
#include <vector>

#include "host/error.hpp"
#include "host/fp_mode.hpp"
#include "host/gemm.hpp"
#include "host/runtime.hpp"

#ifdef STYLERF_HAVE_HOST_BLAS
#include <cblas.h>
#endif

namespace stylerf::host {

bool host_blas_linked() {
#ifdef STYLERF_HAVE_HOST_BLAS
  return true;
#else
  return false;
#endif
}

bool host_blas_usable() {
  return host_blas_linked() && (Runtime::instance().device().type & CL_DEVICE_TYPE_CPU);
}

#ifdef STYLERF_HAVE_HOST_BLAS
// OpenBLAS-specific; weak, so a plain CBLAS without it still links (and then keeps its own threading).
extern "C" void openblas_set_num_threads(int) __attribute__((weak));

namespace {

// Maps each distinct buffer once for the duration of a call and unmaps them on every way out.
class MappedBuffers {
 public:
  float* map(cl_mem mem, bool written) {
    for (auto& m : maps_)
      if (m.mem == mem) return m.ptr;
    size_t bytes = 0;
    check(clGetMemObjectInfo(mem, CL_MEM_SIZE, sizeof(bytes), &bytes, nullptr), "clGetMemObjectInfo");
    cl_int err = CL_SUCCESS;
    // C is mapped for reading too: with beta != 0 sgemm reads it.
    const cl_map_flags flags = written ? CL_MAP_READ | CL_MAP_WRITE : CL_MAP_READ;
    void* p = clEnqueueMapBuffer(Runtime::instance().queue(), mem, CL_TRUE, flags, 0, bytes, 0, nullptr, nullptr,
                                 &err);
    check(err, "clEnqueueMapBuffer", "host-blas GEMM operand");
    maps_.push_back({mem, static_cast<float*>(p)});
    return maps_.back().ptr;
  }
  ~MappedBuffers() {
    for (auto& m : maps_) clEnqueueUnmapMemObject(Runtime::instance().queue(), m.mem, m.ptr, 0, nullptr, nullptr);
  }

 private:
  struct Map {
    cl_mem mem;
    float* ptr;
  };
  std::vector<Map> maps_;
};

// One single-threaded sgemm: a C block and the A rows / B columns it needs.
struct Piece {
  int M, N;
  const float* a;
  const float* b;
  float* c;
};

// The engine's own threads, one per compute unit of the device. OpenBLAS's thread pool would be the
// natural choice, but its workers busy-wait after every call and take the two cores away from the PoCL
// kernels that follow (measured: the Winograd transforms ran 1.8x slower beside it). So OpenBLAS runs
// single-threaded and the work is split here: whole GEMMs of a batch across threads, or a lone GEMM's C
// into row (or column) blocks.
// Set on every call (it is cheap), since code beside the engine may have raised it again.
int engine_threads() {
  if (openblas_set_num_threads) openblas_set_num_threads(1);
  return std::max(1, static_cast<int>(Runtime::instance().device().compute_units));
}

}  // namespace

void host_blas_gemm_batched(Trans ta, Trans tb, int M, int N, int K, float alpha, cl_mem A, size_t a_offset, int lda,
                            size_t a_stride, cl_mem B, size_t b_offset, int ldb, size_t b_stride, float beta, cl_mem C,
                            size_t c_offset, int ldc, size_t c_stride, int batch) {
  if (!host_blas_usable())
    throw Error(host_blas_linked() ? "GEMM engine host-blas runs on CPU OpenCL devices only, not on '" +
                                         Runtime::instance().device().name + "'"
                                   : "GEMM engine host-blas: this build has no CBLAS (install libopenblas-dev and "
                                     "reconfigure)");
  Runtime& rt = Runtime::instance();
  const int threads = engine_threads();
  MappedBuffers maps;
  float* c = maps.map(C, true);  // first, so an A or B sharing C's buffer reuses the writable map
  const float* a = maps.map(A, false);
  const float* b = maps.map(B, false);
  const auto t0 = std::chrono::steady_clock::now();  // after the maps, which wait for the earlier commands

  // Pieces: each GEMM of the batch whole, or, with fewer GEMMs than threads, each cut into blocks of C
  // rows (row-major: A's rows, or A's columns when transposed) or, for wide C, of C columns.
  std::vector<Piece> pieces;
  const int cuts = batch >= threads ? 1 : (threads + batch - 1) / batch;
  const bool by_rows = M >= N;
  for (int i = 0; i < batch; ++i) {
    const float* ai = a + a_offset + i * a_stride;
    const float* bi = b + b_offset + i * b_stride;
    float* ci = c + c_offset + i * c_stride;
    const int extent = by_rows ? M : N;
    const int step = std::max(16, (extent / cuts + 15) / 16 * 16);
    for (int lo = 0; lo < extent; lo += step) {
      const int n = std::min(step, extent - lo);
      if (by_rows)
        pieces.push_back({n, N, ai + (ta == Trans::No ? size_t(lo) * lda : size_t(lo)), bi, ci + size_t(lo) * ldc});
      else
        pieces.push_back({M, n, ai, bi + (tb == Trans::No ? size_t(lo) : size_t(lo) * ldb), ci + lo});
    }
  }
  auto run = [&](size_t first, size_t stride) {
    // Denormals flushed, as in the kernels: with only the kernels flushing, a backdrop-free scene's style
    // steps took 2.65-2.86 s against 1.84-1.89 s with this too (docs/results.md).
    ScopedFlushDenormals flush;
    for (size_t p = first; p < pieces.size(); p += stride)
      cblas_sgemm(CblasRowMajor, ta == Trans::Yes ? CblasTrans : CblasNoTrans,
                  tb == Trans::Yes ? CblasTrans : CblasNoTrans, pieces[p].M, pieces[p].N, K, alpha, pieces[p].a, lda,
                  pieces[p].b, ldb, beta, pieces[p].c, ldc);
  };
  const int used = static_cast<int>(std::min<size_t>(threads, pieces.size()));
  std::vector<std::thread> helpers;
  for (int t = 1; t < used; ++t) helpers.emplace_back(run, t, used);
  run(0, used);
  for (auto& h : helpers) h.join();

  if (rt.profiling())
    rt.record_host("host-blas sgemm",
                   std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
}
#else
void host_blas_gemm_batched(Trans, Trans, int, int, int, float, cl_mem, size_t, int, size_t, cl_mem, size_t, int,
                            size_t, float, cl_mem, size_t, int, size_t, int) {
  throw Error("GEMM engine host-blas: this build has no CBLAS (install libopenblas-dev and reconfigure)");
}
#endif

}  // namespace stylerf::host
