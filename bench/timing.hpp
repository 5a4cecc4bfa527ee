// The one timing loop every benchmark uses: one warm-up call (first launches compile kernels), then the
// best wall time of `repeats` calls, with per-kernel device times of that best run.
#pragma once
#include <cstdio>
#include <functional>
#include <map>
#include <string>

namespace stylerf::bench {

struct Timing {
  double wall_ms = 1e300;                     // best wall time of one call, queue drained
  double kernel_ms = 0;                       // sum of profiled kernel times in that call
  std::map<std::string, double> per_kernel;  // kernel name -> ms in that call
  double kernels_named(std::initializer_list<const char*> names) const;
};

Timing best_of(int repeats, const std::function<void()>& f);

// Under STYLERF_PROFILE=1 (the runtime records every launch): the `top` kernels of the timings gathered
// since the last reset, by total time, printed as a table; returns them as [[kernel, launches, ms], ...]
// JSON text (empty when profiling is off). The patch benches reset at each step, so this is the last step;
// the CLI prints a whole command's under `title`, on stderr.
std::string print_top_kernels(int top, const char* title = "kernels of the last step", std::FILE* out = stdout);

}  // namespace stylerf::bench
