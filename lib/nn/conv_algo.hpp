// Which algorithm a stride-1 "same" 3x3 conv (conv2d_forward / conv2d_backward) runs:
//   im2col      the col matrix in memory, one GEMM per pass (exact to rounding, any size);
//   winograd2   Winograd F(2x2,3x3): 16 GEMMs on transformed tiles, 2.25x fewer multiplies, with forward,
//               dX and dW all in the transformed domain (kernels/winograd.cl);
//   winograd4   F(4x4,3x3): 36 GEMMs, 4x fewer multiplies, more rounding error (bench conv measures it).
// Auto resolves, in order: set_default_conv_algo(), the STYLERF_CONV_ALGO environment variable, then the
// measured choice below. 1x1 convs are a plain GEMM whatever the choice; the strided conv is im2col.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

namespace stylerf::nn {

enum class ConvAlgo { Auto, Im2col, Winograd2, Winograd4 };

const char* conv_algo_name(ConvAlgo a);
ConvAlgo parse_conv_algo(const std::string& name);  // "auto", "im2col", "winograd2", "winograd4"

void set_default_conv_algo(ConvAlgo a);

// The algorithm a 3x3 conv of these sizes runs when asked for `a` (never Auto). Winograd needs its
// largest transformed tensor to fit in 1 GiB (or STYLERF_CONV_SCRATCH_BYTES); otherwise im2col runs.
ConvAlgo resolve_conv_algo(ConvAlgo a, int cin, int cout, int h, int w, int n = 1);

// kernels/winograd.cl's build options for F(m x m, 3 x 3), m = 2 or 4.
std::string winograd_build_options(int m);
// Those of both Winograd algorithms: a stage that builds its programs ahead of its first step builds both.
std::vector<std::string> winograd_build_variants();

}  // namespace stylerf::nn
