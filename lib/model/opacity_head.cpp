#include "lib/model/opacity_head.hpp"

#include "host/error.hpp"

namespace stylerf::model {

Tensor OpacityHead::forward(const Tensor& pos, const Tensor&, std::unique_ptr<Context>*) const {
  return Tensor::full({pos.dim(0), 1}, 1.0f, "opacity head values");
}

void OpacityHead::backward(const Context&, const Tensor&) {
  throw host::Error("OpacityHead: inference only (it has no parameters to train)");
}

const char* surface_depth_name(SurfaceDepth s) { return s == SurfaceDepth::Median ? "median" : "expected"; }

SurfaceDepth parse_surface_depth(const std::string& name) {
  if (name == "expected") return SurfaceDepth::Expected;
  if (name == "median") return SurfaceDepth::Median;
  throw host::SettingError("surface", "must be expected or median (got '" + name + "')");
}

ViewValues render_geometry(const Geometry& g, const scene::Scene& scene, const scene::Camera& cam, int chunk,
                           SurfaceDepth surface) {
  const OpacityHead head;
  return render_camera(g, head, scene, cam, Tensor(), chunk, surface == SurfaceDepth::Median ? 0.5f : 0.0f);
}

}  // namespace stylerf::model
