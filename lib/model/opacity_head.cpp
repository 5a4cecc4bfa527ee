#include "lib/model/opacity_head.hpp"

#include "host/error.hpp"

namespace stylerf::model {

Tensor OpacityHead::forward(const Tensor& pos, const Tensor&, std::unique_ptr<Context>*) const {
  return Tensor::full({pos.dim(0), 1}, 1.0f, "opacity head values");
}

void OpacityHead::backward(const Context&, const Tensor&) {
  throw host::Error("OpacityHead: inference only (it has no parameters to train)");
}

ViewValues render_geometry(const Geometry& g, const scene::Scene& scene, const scene::Camera& cam, int chunk) {
  const OpacityHead head;
  return render_camera(g, head, scene, cam, Tensor(), chunk);
}

}  // namespace stylerf::model
