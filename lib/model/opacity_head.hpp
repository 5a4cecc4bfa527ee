// Geometry alone, rendered: a value head of one constant channel, so a camera's opacity and expected
// depth come from the scene's own weights without any appearance model. The consistency metric
// (lib/eval/consistency.hpp) warps every method's frames with this one geometry, whatever the method.
#pragma once
#include "lib/model/ray_pipeline.hpp"

namespace stylerf::model {

// Value 1 for every kept sample (no parameters, inference only).
class OpacityHead : public SampleHead {
 public:
  int channels() const override { return 1; }
  Tensor forward(const Tensor& pos, const Tensor& dirs, std::unique_ptr<Context>* ctx) const override;
  void backward(const Context& ctx, const Tensor& dvalues) override;
  void collect_params(std::vector<nn::Param*>&) override {}
};

// A whole camera's opacity and depth (ray space, divided by the opacity; 0 where it is ~0). The value
// channel holds the kept opacity.
ViewValues render_geometry(const Geometry& g, const scene::Scene& scene, const scene::Camera& cam,
                           int chunk = 8192);

}  // namespace stylerf::model
