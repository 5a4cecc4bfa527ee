// Stage 2's radiance field of VGG features: a VM feature grid (sum(rank) components per point, TensoRF's
// appearance layout) and a basis matrix (no bias) to C = 256 channels, over a frozen geometry.
//
// Since the basis is linear with no bias, compositing the grid components over the kept samples first and
// applying the basis once per ray is exact:  sum_k w_k (B^T f_k) = B^T (sum_k w_k f_k). That costs
// (kept samples per ray) times fewer basis FLOPs than the per-point order, so render() composites first.
// render_per_point() does it the other way (for the equivalence test, and for heads with a nonlinearity
// per point, such as stage 3's SICT, which must use that order).
//
// Parameters: "feature_grid" (group 0), "feature_basis" [F, C] and, with a background,
// "feature_background" [C], or with a background shell "feature_shell" [texels, C] (group 1).
#pragma once
#include <array>
#include <cstdint>

#include "lib/field/vm_grid.hpp"
#include "lib/model/geometry.hpp"
#include "lib/model/ray_pipeline.hpp"
#include "lib/model/sample_head.hpp"

namespace stylerf::model {

// Per kept sample: the grid's F components (no basis). A SampleHead for the ray pipeline.
class FeatureGridHead : public SampleHead {
 public:
  FeatureGridHead() = default;
  explicit FeatureGridHead(field::VMGrid grid) : res_(grid.res), rank_(grid.rank), grid_("feature_grid", 0, grid.params) {}
  int channels() const override { return rank_[0] + rank_[1] + rank_[2]; }
  Tensor forward(const Tensor& pos, const Tensor& dirs, std::unique_ptr<Context>* ctx) const override;
  void backward(const Context& ctx, const Tensor& dvalues) override;
  void collect_params(std::vector<nn::Param*>& out) override { out.push_back(&grid_); }
  field::VMGrid grid() const { return field::VMGrid::from_params(res_, rank_, grid_.value); }
  nn::Param& grid_param() { return grid_; }

 private:
  std::array<int, 3> res_{}, rank_{};
  nn::Param grid_;
};

struct FeatureFieldConfig {
  std::array<int, 3> rank{48, 48, 48};  // StyleRF: Blender [48,48,48], LLFF [48,12,12]
  int channels = 256;                   // VGG-19 relu3_1
  float init_scale = 0.1f;              // grid factors ~ 0.1 N(0,1) (TensoRF's init)
};

class FeatureField : public nn::Module {
 public:
  FeatureFieldConfig cfg;
  FeatureGridHead head;
  nn::Param basis{"feature_basis", 1, Tensor()};  // [F, C]
  // Scenes whose images have alpha (a background colour) also learn the feature of empty space, [C],
  // composited behind each ray as (1 - acc) * background in the C-channel space: the relu3_1 of the
  // background colour is far from 0, and without it empty pixels would carry an error no parameter can
  // lower. Undefined (no parameter) for scenes without a background.
  nn::Param background{"feature_background", 1, Tensor()};
  // Captures with real surroundings (g.shell on): the features of the background shell's map,
  // [texels, C], composited behind each ray as (1 - acc) * map(exit point) (lib/render/background_shell.hpp).
  nn::Param shell{"feature_shell", 1, Tensor()};

  // Grid at the geometry's resolution; basis U(+-1/sqrt(F)) (PyTorch Linear's default), seeded; a zero
  // background feature when the geometry has a background.
  static FeatureField create(const Geometry& g, const FeatureFieldConfig& cfg, uint64_t seed);
  int channels() const { return cfg.channels; }

  struct Context {
    RayContext rays;
    Tensor composited;  // [R, F] grid components composited over the kept samples
    Tensor rays_acc;    // [R] opacity over all samples (the background's weight is 1 - this)
    render::ShellTaps shell_taps;
  };
  // Features [R, C] (no background: empty space renders as 0), composited first, basis per ray.
  RayResult render(const Geometry& g, const Tensor& origins, const Tensor& dirs, const RayOptions& opt,
                   Context* ctx) const;
  // dfeat [R, C], dkept_acc [R] (either may be undefined): accumulates into the grid and the basis.
  void render_backward(const Geometry& g, const Context& ctx, const Tensor& dfeat, const Tensor& dkept_acc);
  // The same features with the basis applied to every kept sample before compositing (inference only).
  RayResult render_per_point(const Geometry& g, const Tensor& origins, const Tensor& dirs, const RayOptions& opt) const;

  // With a background shell: what empty space adds to each ray, (1 - acc) x the shell's features at the
  // ray's exit point, [R, C] (acc [R]: the rays' opacity). Undefined without a shell.
  Tensor shell_term(const Geometry& g, const Tensor& origins, const Tensor& dirs, const Tensor& acc) const;

  void collect_params(std::vector<nn::Param*>& out) override;
};

}  // namespace stylerf::model
