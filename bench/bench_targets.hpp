// `stylerf bench targets`: perf mode of the stage-2 target reads (kernels/targets.cl) at training sizes:
// the per-ray gather (4096 rays x 256 channels from lego-1/4-sized maps) and its backward, and the patch read
// at the fast profile's scale 4 and the paper profile's scale 1 (GB/s), on a 192x192 patch (256 does not fit
// a 200x200 view).
#pragma once
#include "bench/bench.hpp"

namespace stylerf::bench {

int bench_targets(const BenchOptions& opt);

}  // namespace stylerf::bench
