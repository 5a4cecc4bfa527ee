// `stylerf bench ops`: the perf mode of every NN op kernel, split by op family.
#include <iostream>

#include "bench/bench.hpp"
#include "bench/bench_ops_parts.hpp"
#include "host/runtime.hpp"

namespace stylerf::bench {

int bench_ops(const BenchOptions& opt) {
  std::cout << "device: " << host::Runtime::instance().device().describe() << "\n";
  bench_ops_spatial(opt);
  bench_ops_norm(opt);
  bench_ops_layout(opt);
  bench_ops_style(opt);
  return 0;
}

}  // namespace stylerf::bench
