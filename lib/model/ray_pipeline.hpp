// The ray pipeline shared by every stage:
//   march (box, near/far, jitter when training, alpha-mask skip, early termination evaluating the density
//   as it goes; without it, sigma = density grid on every sample) -> weights
//   (lib/render/weights.hpp) -> keep samples with w >= geometry.weight_threshold (compacted list) -> the
//   value head on the kept samples only -> weighted sum over them (lib/render/composite_values.hpp)
//   (+ (1 - acc) * background when one is given).
// Its backward: composite -> dvalues (-> head.backward, accumulating) and dw of the kept samples; those dw
// (scattered into the full list, zero for dropped samples, whose value is 0 as in TensoRF) plus the
// background term -> weights_backward -> dsigma -> density grid gradient (only when one is asked for:
// the geometry is frozen after stage 1). The sample selection itself has no gradient.
#pragma once
#include <functional>
#include <memory>
#include <vector>

#include "host/tensor.hpp"
#include "lib/model/geometry.hpp"
#include "lib/model/sample_head.hpp"
#include "lib/render/composite.hpp"
#include "lib/render/composite_values.hpp"
#include "lib/render/weights.hpp"
#include "lib/scene/scene.hpp"

namespace stylerf::model {

struct RayOptions {
  bool jitter = false;  // training: random offset of each ray's first sample
  uint32_t seed = 0;
  uint32_t ray_base = 0;  // the first ray's index in the jitter (render::MarchConfig::ray_base)
  Tensor background;    // [C] composited behind the rays, or undefined (none)
};

struct RayResult {
  Tensor value;     // [R, C]
  Tensor acc;       // [R] opacity over all samples
  Tensor kept_acc;  // [R] opacity over the kept samples (what the values were composited with)
  Tensor depth;     // [R] sum w t over all samples (not divided by acc)
  int64_t samples = 0, kept = 0;
};

// What render_rays_backward needs.
struct RayContext {
  render::Samples samples;
  Tensor sigma;
  render::Weights weights;
  render::Kept kept;
  render::KeptLayout kept_layout;
  Tensor kept_w;
  Tensor kept_values;
  std::unique_ptr<SampleHead::Context> head;
  Tensor background;
  // What a model shading the composited values per ray keeps for its backward (a deferred head,
  // lib/render/deferred.hpp); the pipeline itself leaves it empty.
  std::unique_ptr<SampleHead::Context> shading;
  // A background shell composited by the model after the pipeline: its taps and the opacity it used.
  struct Shell {
    render::ShellTaps taps;
    Tensor acc;
  } shell;
};

// origins, dirs [R,3] in the ray space.
RayResult render_rays(const Geometry& g, const SampleHead& head, const Tensor& origins, const Tensor& dirs,
                      const RayOptions& opt, RayContext* ctx);

// dvalue [R, C], dkept_acc [R] (either may be undefined). The head's gradients are accumulated; when
// ddensity is given, the density grid's gradient is added to it. dacc [R] (optional): a gradient w.r.t. the
// opacity over all samples from terms composited after the pipeline (a background added by the caller).
// dweights [S] (optional): a gradient w.r.t. every sample's weight from a term on the weights themselves
// (the density stage's distortion term).
void render_rays_backward(const Geometry& g, SampleHead& head, const RayContext& ctx, const Tensor& dvalue,
                          const Tensor& dkept_acc, Tensor* ddensity, const Tensor& dacc = Tensor(),
                          const Tensor& dweights = Tensor());

// Rays in groups of `group` consecutive rays (the sub-rays of one footprint, e.g. a feature-map block),
// each group rendered as one ray the way multisample anti-aliasing splits coverage from shading: the
// geometry per sub-ray (march, weights, the kept samples), the value once per depth slab of the group
// (steps_per_point march steps deep). The `attributes` head runs on every kept sample; its attributes are
// merged per slab across the group (lib/render/step_merge.hpp: weight-averaged, the merged weight summed
// over the group's size); `shade` maps merged attributes [M, A] to values [M, C], which are composited per
// group. For a shade linear in the attributes this is exactly the mean of the sub-rays' composites,
// whatever the slab; for a nonlinear one (SICT) it costs one shade per merged point instead of one per
// sub-ray sample.
using ShadeFn = std::function<Tensor(const Tensor& attributes)>;
struct GroupResult {
  Tensor value;     // [R / group, C]
  Tensor kept_acc;  // [R / group] the merged weights' sum: the mean kept opacity of the group's rays
  Tensor acc;       // [R] per sub-ray, as render_rays
  Tensor depth;     // [R] per sub-ray, as render_rays
  int64_t samples = 0, kept = 0, merged = 0;
};
// No background and no jitter (inference). origins, dirs [R, 3] with R a multiple of group.
GroupResult render_ray_groups(const Geometry& g, const SampleHead& attributes, const ShadeFn& shade, int channels,
                              const Tensor& origins, const Tensor& dirs, int group, int steps_per_point = 1);

// A whole camera in chunks of rays (bounded memory): interleaved values [H*W*C], acc and depth [H*W]
// (depth divided by acc where acc > 1e-6, else 0). A chunk holds at most kMaxSamplesPerCall / max_samples
// rays, whatever `chunk` says.
constexpr int64_t kMaxSamplesPerCall = int64_t(1) << 21;
// The rays of one renderer call asked `chunk`, bounded so that every ray keeping all of its samples stays
// within kMaxSamplesPerCall.
int64_t rays_per_call(const Geometry& g, int64_t chunk);
struct ViewValues {
  int width = 0, height = 0, channels = 0;
  std::vector<float> value, acc, depth;
};
ViewValues render_camera(const Geometry& g, const SampleHead& head, const scene::Scene& scene,
                         const scene::Camera& cam, const Tensor& background, int chunk = 8192);
// The same loop for a model that renders rays its own way (C channels per ray): render(origins, dirs).
using RenderRaysFn = std::function<RayResult(const Tensor& origins, const Tensor& dirs)>;
ViewValues render_camera(const Geometry& g, int channels, const RenderRaysFn& render, const scene::Scene& scene,
                         const scene::Camera& cam, int chunk = 8192);

}  // namespace stylerf::model
