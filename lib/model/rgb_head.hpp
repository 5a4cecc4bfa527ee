// The stage-1 value head: TensoRF's appearance grid (a VM grid of sum(rank) features per point) and its
// MLP (lib/field/appearance_head.hpp) giving RGB in [0,1] per kept sample. Parameters: "app" (a grid,
// group 0) and "head.basis", "head.w1" .. "head.b3" (the network, group 1).
#pragma once
#include <array>

#include "lib/field/appearance_head.hpp"
#include "lib/field/vm_grid.hpp"
#include "lib/model/sample_head.hpp"

namespace stylerf::model {

class RgbHead : public SampleHead {
 public:
  RgbHead() = default;
  RgbHead(field::VMGrid app, const field::AppearanceHead& mlp);

  int channels() const override { return 3; }
  bool wants_view_dirs() const override { return cfg_.view_dependent; }
  Tensor forward(const Tensor& pos, const Tensor& dirs, std::unique_ptr<Context>* ctx) const override;
  void backward(const Context& ctx, const Tensor& dvalues) override;
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
};

}  // namespace stylerf::model
