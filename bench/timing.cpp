#include "bench/timing.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <vector>

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

std::string print_top_kernels(int top, const char* title, std::FILE* out) {
  auto& rt = host::Runtime::instance();
  if (!rt.profiling()) return "";
  std::vector<host::KernelTiming> t = rt.timings();
  std::sort(t.begin(), t.end(), [](const auto& a, const auto& b) { return a.total_ms > b.total_ms; });
  double total = 0;
  for (const auto& k : t) total += k.total_ms;
  std::fprintf(out, "%s (STYLERF_PROFILE=1): %.3f ms in all, top %d\n", title, total, top);
  std::string json = "[";
  for (int i = 0; i < int(t.size()) && i < top; ++i) {
    std::fprintf(out, "  %-40s %5d launches %9.3f ms\n", t[i].kernel.c_str(), t[i].launches, t[i].total_ms);
    json += std::string(i ? ", " : "") + "[\"" + t[i].kernel + "\", " + std::to_string(t[i].launches) + ", " +
            std::to_string(t[i].total_ms) + "]";
  }
  return json + "]";
}

}  // namespace stylerf::bench
