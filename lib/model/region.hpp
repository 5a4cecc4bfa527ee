// 3D regions for compositional style transfer (StyleRF Sec. 4, "compositional 3D style transfer"): a region
// in scene coordinates is rendered as its indicator (1 inside, 0 outside) composited with the scene's own
// weights, so its per-pixel soft mask is the same surface in every view (kernels/region.cl).
//
// Specs (world units of the scene's loaded cameras):
//   box:x0,y0,z0,x1,y1,z1     an axis-aligned box
//   sphere:x,y,z,r            a ball
//   depth:d0,d1               points whose distance along the camera path's mean viewing direction,
//                             measured from the path's centre (mean camera position), lies in [d0, d1];
//                             d1 may be "inf". The natural choice for forward-facing captures.
#pragma once
#include <array>
#include <string>
#include <vector>

#include "host/tensor.hpp"
#include "lib/model/geometry.hpp"
#include "lib/model/sample_head.hpp"
#include "lib/scene/scene.hpp"

namespace stylerf::model {

struct Region {
  enum Kind { Box = 0, Sphere = 1, Slab = 2 };
  Kind kind = Box;
  std::array<float, 8> p{};  // box lo, hi | sphere centre, r | slab centre, unit axis, d0, d1
  std::string spec;          // as given

  // Throws host::Error naming the option and what is wrong. `path` gives a depth interval its centre and
  // axis (required for depth:).
  static Region parse(const std::string& spec, const std::vector<scene::Camera>& path);
  bool contains(const std::array<double, 3>& world) const;  // the double-precision reference
};

// The ray-space -> world map the indicator needs: the box the positions are normalised by and, for NDC
// scenes, the inverse projection (W/2fx, H/2fy of the capture's cameras, the near plane).
struct RegionSpace {
  std::array<float, 3> lo{}, hi{};
  bool ndc = false;
  float sx = 1, sy = 1, near = 1;
  static RegionSpace of(const Geometry& g, const scene::Scene& scene);
  // World point of a normalised position (double, for references and tests). NDC positions at the far end
  // (ray-space z >= 1) are infinitely far: at_infinity says so and world() must not be used for them.
  std::array<double, 3> world(const std::array<double, 3>& pos) const;
  bool at_infinity(const std::array<double, 3>& pos) const;
  // The double-precision reference of the kernel: whether the point at a normalised position is inside.
  bool contains(const Region& r, const std::array<double, 3>& pos) const;
};

// pos [K,3] normalised to the box -> [K] of 0/1.
host::Tensor region_indicator(const host::Tensor& pos, const Region& region, const RegionSpace& space);

// A value head of one channel: the region's indicator (no parameters, inference only; the indicator has
// no useful gradient).
class RegionHead : public SampleHead {
 public:
  RegionHead(Region region, RegionSpace space) : region_(std::move(region)), space_(space) {}
  int channels() const override { return 1; }
  Tensor forward(const Tensor& pos, const Tensor& dirs, std::unique_ptr<Context>* ctx) const override;
  void backward(const Context& ctx, const Tensor& dvalues) override;
  void collect_params(std::vector<nn::Param*>&) override {}

 private:
  Region region_;
  RegionSpace space_;
};

}  // namespace stylerf::model
