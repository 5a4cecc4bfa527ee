// `stylerf bench ops`: the perf mode of every NN op kernel, split by op family.
#include <algorithm>
#include <iostream>

#include "bench/bench.hpp"
#include "bench/bench_ops_parts.hpp"
#include "host/runtime.hpp"

namespace stylerf::bench {

int bench_ops(const BenchOptions& opt) {
  std::cout << "device: " << host::Runtime::instance().device().describe() << "\n";
  // --parts picks families (default: all).
  auto on = [&](const char* family) {
    return opt.parts.empty() || std::find(opt.parts.begin(), opt.parts.end(), family) != opt.parts.end();
  };
  if (on("spatial")) bench_ops_spatial(opt);
  if (on("norm")) bench_ops_norm(opt);
  if (on("layout")) bench_ops_layout(opt);
  if (on("style")) bench_ops_style(opt);
  if (on("eval")) bench_ops_eval(opt);
  if (on("shell")) bench_ops_shell(opt);
  return 0;
}

}  // namespace stylerf::bench
