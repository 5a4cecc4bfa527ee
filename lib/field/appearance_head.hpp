// TensoRF's appearance head: grid features [S, F] -> basis matrix (no bias) to 27 dims -> MLP
// 27 (+ view encoding) -> 128 -> 128 -> 3 with ReLU between and a sigmoid at the end. Weights are stored
// [in, out] row-major so a layer is y = x W + b (one GEMM, host/gemm.hpp).
//
// View dependence is off unless asked for (the paper disables it for its feature stage); when on, the MLP
// input is [h (27), d (3), sin(2^k d), cos(2^k d) for k < view_pe] with d the unit view direction.
#pragma once
#include <cstdint>
#include <vector>

#include "host/tensor.hpp"

namespace stylerf::field {

using host::Tensor;

struct AppearanceHeadConfig {
  int features = 72;  // F = sum of the appearance grid's ranks
  int basis_dim = 27;
  int hidden = 128;
  bool view_dependent = false;
  int view_pe = 2;  // frequencies of the view-direction encoding (when view_dependent)
  int input_dim() const { return basis_dim + (view_dependent ? 3 + 6 * view_pe : 0); }
};

struct AppearanceHead {
  AppearanceHeadConfig cfg;
  Tensor basis;      // [F, basis_dim]
  Tensor w1, b1;     // [D, hidden], [hidden]
  Tensor w2, b2;     // [hidden, hidden], [hidden]
  Tensor w3, b3;     // [hidden, 3], [3]

  // PyTorch Linear's default init (U(+-1/sqrt(fan_in)) weights and biases), last bias 0 as TensoRF; seeded.
  static AppearanceHead create(const AppearanceHeadConfig& cfg, uint64_t seed);
  // Parameters in a fixed order (basis, w1, b1, w2, b2, w3, b3), for optimisers and checkpoints.
  std::vector<Tensor*> params();
};

// Activations kept by forward for backward.
struct HeadCache {
  Tensor feat, in, h1, h2, rgb;  // in: MLP input [S, D] (the basis output when view dependence is off)
};

// feat [S, F]; view_dirs [S, 3] (per sample) when cfg.view_dependent, else ignored. Returns rgb [S, 3].
Tensor appearance_forward(const AppearanceHead& head, const Tensor& feat, const Tensor& view_dirs,
                          HeadCache* cache);

struct HeadGrads {
  Tensor basis, w1, b1, w2, b2, w3, b3;  // fresh tensors, same shapes as the parameters
  Tensor dfeat;                          // [S, F]
  std::vector<Tensor*> params();        // same order as AppearanceHead::params
};
HeadGrads appearance_backward(const AppearanceHead& head, const HeadCache& cache, const Tensor& drgb);

}  // namespace stylerf::field
