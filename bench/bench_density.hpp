// `stylerf bench density [--json FILE] [--quick]`: accuracy against time for the density stage.
//   1. lego at 1/4 resolution and fern at 1/8: held-out PSNR against training wall time (evaluation time
//      excluded), written as JSON and as a PNG plot (density_psnr_vs_time.png beside the JSON, or in the
//      current directory);
//   2. what the knobs cost on lego: step size (samples per ray), final grid resolution, rank, alpha mask
//      on/off -> seconds per iteration and PSNR after the same training time.
// Full runs: 30 minutes per scene and 5 minutes per knob; --quick: a few hundred iterations / ~1 minute.
// The TensoRF schedule (events at 2000..5500 of 30000 iterations) is compressed to the number of
// iterations the time budget allows, measured by a short warm-up run.
// Data: $STYLERF_DATA, else ../shared/data, else ../../shared/data (scenes/blender/lego, scenes/llff/fern).
#pragma once
#include "bench/bench.hpp"

namespace stylerf::bench {

int bench_density(const BenchOptions& opt);

}  // namespace stylerf::bench
