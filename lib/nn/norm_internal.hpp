// Internals shared by norm.cpp and loss.cpp: statistics that keep the mean's rounding residual.
//
// A float mean of data like 1e4 +- 1e-2 is only good to half an ulp of 1e4 (5% of that std). The stats
// kernel also returns mean_lo, the residual (true mean ~ mean + mean_lo); kernels that subtract the
// mean subtract both, so (x - mean) keeps its digits. The public ChannelStats has no room for it, so
// ops that recompute statistics internally (AdaIN, style loss) use these.
#pragma once
#include "lib/nn/ops.hpp"

namespace stylerf::nn::detail {

struct PreciseStats {
  ChannelStats stats;  // mean, std [N,C]
  Tensor mean_lo;      // [N,C]
};

// op names the public op in error messages.
PreciseStats channel_stats_precise(const Tensor& x, float eps, const char* op, const char* name);

// channel_stats_backward with the residual (mean_lo may be undefined: then plain float mean).
Tensor channel_stats_backward_precise(const Tensor& x, const ChannelStats& stats, const Tensor& mean_lo,
                                      const Tensor& dmean, const Tensor& dstd, const char* op);

}  // namespace stylerf::nn::detail
