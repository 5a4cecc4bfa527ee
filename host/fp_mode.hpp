// Flush-to-zero and denormals-are-zero for host code that runs the library's arithmetic (the host-BLAS GEMM
// engine): the host-side match of the kernels' -cl-denorms-are-zero (host/runtime.cpp says why). x86 CPUs
// take a slow path for every float below 1e-38 unless the thread flushes them; the scope sets the calling
// thread's MXCSR FTZ and DAZ bits and puts them back as they were when it ends, so a caller's own arithmetic
// keeps its mode.
#pragma once

#if defined(__SSE__) || defined(__x86_64__)
#include <xmmintrin.h>
#endif

namespace stylerf::host {

class ScopedFlushDenormals {
 public:
#if defined(__SSE__) || defined(__x86_64__)
  ScopedFlushDenormals() : saved_(_mm_getcsr()) { _mm_setcsr(saved_ | kBits); }
  // Only the two bits go back: exception flags raised inside the scope stay, as they would without it.
  ~ScopedFlushDenormals() { _mm_setcsr((_mm_getcsr() & ~kBits) | (saved_ & kBits)); }

 private:
  static constexpr unsigned kBits = 0x8040;  // FTZ (bit 15) | DAZ (bit 6)
  unsigned saved_;
#else
  ScopedFlushDenormals() = default;
#endif
 public:
  ScopedFlushDenormals(const ScopedFlushDenormals&) = delete;
  ScopedFlushDenormals& operator=(const ScopedFlushDenormals&) = delete;
};

}  // namespace stylerf::host
