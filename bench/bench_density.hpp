// `stylerf bench density [--json FILE] [--quick]`: accuracy against time for the density stage.
//   1. lego at 1/4 resolution and fern at 1/8: held-out PSNR against training wall time (evaluation time
//      excluded), written as JSON and as a PNG plot (density_psnr_vs_time.png beside the JSON, or in the
//      current directory);
//   2. what the knobs cost on lego: step size (samples per ray), final grid resolution, rank, alpha mask
//      on/off -> seconds per iteration and PSNR after the same training time.
// Full runs: 30 minutes per scene and 5 minutes per knob; --quick: a few hundred iterations / ~1 minute.
// --budget / --knob-budget set those times, --parts lego,fern,knobs picks what runs; the JSON and the plot
// are rewritten after every part.
// The TensoRF schedule (events at 2000..5500 of 30000 iterations) is fitted to the number of iterations
// the time budget allows, re-estimated from the step rate as the run goes (as `train-density --minutes`).
// Data: $STYLERF_DATA, else ../shared/data, else ../../shared/data (scenes/blender/lego, scenes/llff/fern).
#pragma once
#include "bench/bench.hpp"

namespace stylerf::bench {

int bench_density(const BenchOptions& opt);

}  // namespace stylerf::bench
