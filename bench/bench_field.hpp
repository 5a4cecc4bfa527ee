// `stylerf bench field`: perf modes of the density-stage kernels (kernels/grid.cl, kernels/render.cl) at
// training sizes: VM grid sampling forward/backward (million points/s, GB/s), alpha-mask build, ray
// marching (rays/s), compositing forward/backward (GB/s), appearance head forward/backward.
#pragma once
#include "bench/bench.hpp"

namespace stylerf::bench {

int bench_field(const BenchOptions& opt);

}  // namespace stylerf::bench
