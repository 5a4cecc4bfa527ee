#include "bench/timing.hpp"

#include <chrono>

#include "host/runtime.hpp"

namespace stylerf::bench {

double Timing::kernels_named(std::initializer_list<const char*> names) const {
  double s = 0;
  for (const char* n : names)
    if (auto it = per_kernel.find(n); it != per_kernel.end()) s += it->second;
  return s;
}

Timing best_of(int repeats, const std::function<void()>& f) {
  auto& rt = host::Runtime::instance();
  const bool was_profiling = rt.profiling();
  f();
  rt.finish();
  Timing best;
  for (int r = 0; r < repeats; ++r) {
    rt.reset_timings();
    rt.set_profiling(true);
    auto t0 = std::chrono::steady_clock::now();
    f();
    rt.finish();
    const double wall = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    Timing t;
    t.wall_ms = wall;
    for (const auto& k : rt.timings()) {
      t.kernel_ms += k.total_ms;
      t.per_kernel[k.kernel] = k.total_ms;
    }
    rt.set_profiling(was_profiling);
    if (wall < best.wall_ms) best = std::move(t);
  }
  return best;
}

}  // namespace stylerf::bench
