// `stylerf bench targets`: the stage-2 targets (kernels/targets.cl, lib/features) at training sizes.
//  1. Reads, for each stored dtype (f32, f16): the per-ray gather (4096 rays x 256 channels from
//     lego-1/4-sized maps) and its backward (f32 only: float atomics), and the patch read at the fast
//     profile's scale 4 and the paper profile's scale 1 (GB/s), on a 192x192 patch (256 does not fit a
//     200x200 view).
//  2. Storage choices for lego at 1/4 (200x200) and at its own 800x800, 100 views: the maps' memory, what a
//     training step pays to read its targets, and what the targets cost once (VGG over every view, then the
//     cache file). "per patch" computes relu3_1 of each step's patch instead of storing maps: no memory, a
//     VGG forward every step. Needs the VGG weights (scripts/fetch_weights.sh); without them this part says
//     so and stops.
#pragma once
#include "bench/bench.hpp"

namespace stylerf::bench {

int bench_targets(const BenchOptions& opt);

}  // namespace stylerf::bench
