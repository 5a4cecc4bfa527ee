// The stage-1 value head: TensoRF's appearance grid (a VM grid of sum(rank) features per point) and its
// MLP (lib/field/appearance_head.hpp) giving RGB in [0,1] per kept sample. Parameters: "app" (a grid,
// group 0) and "head.basis", "head.w1" .. "head.b3" (the network, group 1).
#pragma once
#include <array>

#include "lib/field/appearance_head.hpp"
#include "lib/field/vm_grid.hpp"
#include "lib/model/sample_head.hpp"

namespace stylerf::model {

// Two ways to shade (DensityModelConfig::shading):
// - per sample (TensoRF): the head's values are RGB, each kept sample through basis + MLP, then composited;
// - deferred (lib/render/deferred.hpp): the head's values are the raw appearance features (sum of ranks
//   channels), composited by the pipeline; shade() then runs basis + MLP once per ray on their weighted
//   mean and scales by the opacity. One MLP evaluation per ray instead of per kept sample.
class RgbHead : public SampleHead {
 public:
  RgbHead() = default;
  RgbHead(field::VMGrid app, const field::AppearanceHead& mlp, bool deferred = false);

  bool deferred() const { return deferred_; }
  int channels() const override { return deferred_ ? rank_[0] + rank_[1] + rank_[2] : 3; }
  bool wants_view_dirs() const override { return cfg_.view_dependent && !deferred_; }
  Tensor forward(const Tensor& pos, const Tensor& dirs, std::unique_ptr<Context>* ctx) const override;
  void backward(const Context& ctx, const Tensor& dvalues) override;

  // Deferred shading of composited features F [R, F] with opacity kept_acc [R] (and ray directions
  // [R,3] when view-dependent): rgb [R,3] before any background.
  Tensor shade(const Tensor& F, const Tensor& kept_acc, const Tensor& dirs, std::unique_ptr<Context>* ctx) const;
  // drgb [R,3] -> the MLP's gradients accumulated; returns dF and sets dkept_acc.
  Tensor shade_backward(const Context& ctx, const Tensor& drgb, Tensor& dkept_acc);
  void collect_params(std::vector<nn::Param*>& out) override;

  // Views of the parameters (shallow: they share the parameters' buffers).
  field::VMGrid app() const { return field::VMGrid::from_params(res_, rank_, app_.value); }
  field::AppearanceHead mlp() const;
  // Replaces the appearance grid (upsampling, cropping); its gradient is dropped.
  void set_app(const field::VMGrid& g);
  nn::Param& app_param() { return app_; }

 private:
  std::array<int, 3> res_{}, rank_{};
  field::AppearanceHeadConfig cfg_;
  nn::Param app_;
  nn::Param mlp_[7];  // basis, w1, b1, w2, b2, w3, b3
  bool deferred_ = false;
};

}  // namespace stylerf::model
