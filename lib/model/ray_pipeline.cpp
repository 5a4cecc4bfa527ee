#include "lib/model/ray_pipeline.hpp"

#include <algorithm>

#include "host/error.hpp"
#include "lib/field/vm_grid.hpp"
#include "lib/nn/ops.hpp"
#include "lib/render/step_merge.hpp"
#include "lib/scene/rays.hpp"

namespace stylerf::model {

using host::Error;

// Rays with no samples at all (every ray missed the box, or all its voxels are empty): value 0 plus the
// background, acc 0, depth 0.
static RayResult empty_result(int64_t R, int C, const Tensor& background) {
  RayResult out;
  out.value = Tensor::zeros({R, C}, "rendered values");
  out.acc = Tensor::zeros({R}, "rendered acc");
  out.kept_acc = Tensor::zeros({R}, "rendered kept acc");
  out.depth = Tensor::zeros({R}, "rendered depth");
  if (background.defined() && R > 0) render::background_forward(out.value, out.acc, background);
  return out;
}

RayResult render_rays(const Geometry& g, const SampleHead& head, const Tensor& origins, const Tensor& dirs,
                      const RayOptions& opt, RayContext* ctx) {
  const int64_t R = origins.dim(0);
  const int C = head.channels();
  if (opt.background.defined()) host::expect_shape(opt.background, {C}, "render_rays", "background");
  render::DensityMarch ert;
  ert.grid = &g.density;
  ert.act = g.act;
  ert.ert_threshold = g.ert_threshold;
  render::Samples s = render::march(origins, dirs, g.march_config(opt.jitter, opt.seed, opt.ray_base), g.active_mask(),
                                    g.ert_threshold > 0.0f ? &ert : nullptr);
  if (ctx) {
    *ctx = RayContext{};
    ctx->samples = s;
    ctx->background = opt.background;
  }
  if (s.count == 0) return empty_result(R, C, opt.background);

  Tensor sigma = s.sigma.defined() ? s.sigma : field::density_forward(g.density, s.positions, g.act);
  render::Weights w = render::weights_forward(s, sigma);
  render::Kept k = render::keep_by_weight(s, w.w, g.weight_threshold);

  render::KeptLayout layout;
  layout.count = k.count;
  layout.ray_offset = k.ray_offset;
  layout.ray_count = k.ray_count;
  RayResult out;
  out.acc = w.acc;
  out.depth = w.depth;
  out.samples = s.count;
  out.kept = k.count;
  Tensor kept_w, values;
  std::unique_ptr<SampleHead::Context> hctx;
  if (k.count > 0) {
    layout.ray_index = render::gather_rows(s.ray_index, k.index, k.count);
    kept_w = render::gather_rows(w.w, k.index, k.count);
    Tensor pos = render::gather_rows(s.positions, k.index, k.count);
    Tensor view_dirs;
    if (head.wants_view_dirs()) view_dirs = render::gather_rows(dirs, layout.ray_index, k.count);
    values = head.forward(pos, view_dirs, ctx ? &hctx : nullptr);
    if (values.ndim() != 2 || values.dim(0) != k.count || values.dim(1) != C)
      throw Error("render_rays: the value head returned shape " + host::shape_str(values.shape()) + ", expected [" +
                  std::to_string(k.count) + ", " + std::to_string(C) + "]");
    render::CompositedValues cv = render::composite_values_forward(layout, kept_w, values);
    out.value = cv.value;
    out.kept_acc = cv.acc;
  } else {
    out.value = Tensor::zeros({R, C}, "rendered values");
    out.kept_acc = Tensor::zeros({R}, "rendered kept acc");
  }
  if (opt.background.defined()) render::background_forward(out.value, out.acc, opt.background);
  if (ctx) {
    ctx->sigma = sigma;
    ctx->weights = w;
    ctx->kept = k;
    ctx->kept_layout = layout;
    ctx->kept_w = kept_w;
    ctx->kept_values = values;
    ctx->head = std::move(hctx);
  }
  return out;
}

void render_rays_backward(const Geometry& g, SampleHead& head, const RayContext& ctx, const Tensor& dvalue,
                          const Tensor& dkept_acc, Tensor* ddensity, const Tensor& dacc_after,
                          const Tensor& dweights) {
  const render::Samples& s = ctx.samples;
  if (s.count == 0) return;
  Tensor dw_full;  // [S]: gradient w.r.t. every sample's weight
  if (ctx.kept.count > 0) {
    render::CompositeValuesGrads cg =
        render::composite_values_backward(ctx.kept_layout, ctx.kept_w, ctx.kept_values, dvalue, dkept_acc);
    if (dvalue.defined()) head.backward(*ctx.head, cg.dvalues);
    if (ddensity) dw_full = render::scatter_rows(cg.dw, ctx.kept.index, s.count);
  }
  if (!ddensity) return;
  if (dweights.defined()) {
    host::expect_shape(dweights, {s.count}, host::DType::F32, "render_rays_backward", "dweights");
    if (dw_full.defined())
      nn::axpby(1.0f, dweights, 1.0f, dw_full);
    else
      dw_full = dweights;
  }
  Tensor dacc;  // the background term's gradient w.r.t. the opacity of all samples
  if (ctx.background.defined() && dvalue.defined()) render::background_backward(dvalue, ctx.background, dacc, false);
  if (dacc_after.defined()) {
    host::expect_shape(dacc_after, {ctx.samples.ray_count.numel()}, host::DType::F32, "render_rays_backward", "dacc");
    if (dacc.defined())
      nn::axpby(1.0f, dacc_after, 1.0f, dacc);
    else
      dacc = dacc_after;
  }
  Tensor dsigma = render::weights_backward(s, ctx.sigma, dw_full, dacc, Tensor());
  field::density_backward(g.density, s.positions, ctx.sigma, dsigma, *ddensity, g.act);
}

GroupResult render_ray_groups(const Geometry& g, const SampleHead& attributes, const ShadeFn& shade, int channels,
                              const Tensor& origins, const Tensor& dirs, int group, int steps_per_point) {
  const int64_t R = origins.dim(0);
  if (group < 1 || R % group != 0)
    throw Error("render_ray_groups: " + std::to_string(R) + " rays are not whole groups of " + std::to_string(group));
  if (steps_per_point < 1)
    throw Error("render_ray_groups: steps_per_point must be >= 1, got " + std::to_string(steps_per_point));
  const int64_t B = R / group;
  const int C = channels;
  render::DensityMarch ert;
  ert.grid = &g.density;
  ert.act = g.act;
  ert.ert_threshold = g.ert_threshold;
  const render::MarchConfig mc = g.march_config(false, 0);
  render::Samples s = render::march(origins, dirs, mc, g.active_mask(), g.ert_threshold > 0.0f ? &ert : nullptr);
  GroupResult out;
  out.value = Tensor::zeros({B, C}, "group values");
  out.kept_acc = Tensor::zeros({B}, "group kept acc");
  if (s.count == 0) {
    out.acc = Tensor::zeros({R}, "rendered acc");
    out.depth = Tensor::zeros({R}, "rendered depth");
    return out;
  }
  Tensor sigma = s.sigma.defined() ? s.sigma : field::density_forward(g.density, s.positions, g.act);
  render::Weights w = render::weights_forward(s, sigma);
  render::Kept k = render::keep_by_weight(s, w.w, g.weight_threshold);
  out.acc = w.acc;
  out.depth = w.depth;
  out.samples = s.count;
  out.kept = k.count;
  if (k.count == 0) return out;
  const Tensor ray_index = render::gather_rows(s.ray_index, k.index, k.count);
  const Tensor kept_w = render::gather_rows(w.w, k.index, k.count);
  const Tensor kept_t = render::gather_rows(s.t, k.index, k.count);
  const Tensor pos = render::gather_rows(s.positions, k.index, k.count);
  Tensor view_dirs;
  if (attributes.wants_view_dirs()) view_dirs = render::gather_rows(dirs, ray_index, k.count);
  const Tensor attr = attributes.forward(pos, view_dirs, nullptr);  // [K, A]
  const render::StepMerge m = render::merge_group_steps(ray_index.to_host_i32(), kept_t.to_host(), kept_w.to_host(), R,
                                                        group, mc.step * float(steps_per_point));
  const int64_t M = m.points();
  out.merged = M;
  // The merged attributes: the weighted mean of each point's members (a composite over `order` with the
  // shares as weights, reading the members' rows in place).
  const int64_t K = k.count;
  const Tensor order = Tensor::from_host(m.order, {K}, "merge order");
  render::KeptLayout members;
  members.count = K;
  members.ray_offset = Tensor::from_host(m.point_offset, {M}, "merged point offsets");
  members.ray_count = Tensor::from_host(m.point_count, {M}, "merged point counts");
  const Tensor merged_attr =
      render::composite_values_forward(members, Tensor::from_host(m.share, {K}, "merge shares"), attr, order).value;
  const Tensor values = shade(merged_attr);
  if (values.ndim() != 2 || values.dim(0) != M || values.dim(1) != C)
    throw Error("render_ray_groups: shade returned shape " + host::shape_str(values.shape()) + ", expected [" +
                std::to_string(M) + ", " + std::to_string(C) + "]");
  render::KeptLayout points;
  points.count = M;
  points.ray_offset = Tensor::from_host(m.group_offset, {B}, "group offsets");
  points.ray_count = Tensor::from_host(m.group_count, {B}, "group counts");
  render::CompositedValues cv =
      render::composite_values_forward(points, Tensor::from_host(m.point_weight, {M}, "merged weights"), values);
  out.value = cv.value;
  out.kept_acc = cv.acc;
  return out;
}

ViewValues render_camera(const Geometry& g, const SampleHead& head, const scene::Scene& scene,
                         const scene::Camera& cam, const Tensor& background, int chunk) {
  RayOptions opt;
  opt.background = background;
  return render_camera(
      g, head.channels(),
      [&](const Tensor& o, const Tensor& d) { return render_rays(g, head, o, d, opt, nullptr); }, scene, cam,
      chunk);
}

int64_t rays_per_call(const Geometry& g, int64_t chunk) {
  return std::max<int64_t>(1, std::min<int64_t>(chunk, kMaxSamplesPerCall / std::max<int64_t>(1, g.max_samples)));
}

ViewValues render_camera(const Geometry& g, int channels, const RenderRaysFn& render, const scene::Scene& scene,
                         const scene::Camera& cam, int chunk) {
  if (chunk < 1) throw Error("render_camera: chunk must be >= 1");
  const scene::Rays rays = scene::camera_rays(scene, cam);
  const int64_t n = static_cast<int64_t>(rays.size());
  const int C = channels;
  ViewValues v;
  v.width = cam.width;
  v.height = cam.height;
  v.channels = C;
  v.value.resize(size_t(n) * C);
  v.acc.resize(size_t(n));
  v.depth.resize(size_t(n));
  // Every ray of a call may keep all of its samples, and a head holds per-sample activations (the RGB
  // MLP: [kept, 128] floats), so a call is bounded to kMaxSamplesPerCall possible samples (1 GiB of such
  // activations) whatever chunk is asked for: dense NDC scenes reach ~1700 samples a ray, and 8192 rays
  // of them asked for a 2.7 GB buffer, beyond PoCL's 2 GiB per-buffer limit.
  const int64_t step = rays_per_call(g, chunk);
  for (int64_t b = 0; b < n; b += step) {
    const int64_t R = std::min<int64_t>(step, n - b);
    std::vector<float> o(rays.origins.begin() + 3 * b, rays.origins.begin() + 3 * (b + R));
    std::vector<float> d(rays.directions.begin() + 3 * b, rays.directions.begin() + 3 * (b + R));
    RayResult out = render(Tensor::from_host(o, {R, 3}, "render origins"), Tensor::from_host(d, {R, 3}, "render directions"));
    if (out.value.ndim() != 2 || out.value.dim(0) != R || out.value.dim(1) != C)
      throw Error("render_camera: a chunk of " + std::to_string(R) + " rays rendered to shape " +
                  host::shape_str(out.value.shape()) + ", expected [" + std::to_string(R) + ", " + std::to_string(C) + "]");
    const auto val = out.value.to_host(), acc = out.acc.to_host(), depth = out.depth.to_host();
    std::copy(val.begin(), val.end(), v.value.begin() + int64_t(C) * b);
    for (int64_t i = 0; i < R; ++i) {
      v.acc[size_t(b + i)] = acc[size_t(i)];
      v.depth[size_t(b + i)] = acc[size_t(i)] > 1e-6f ? depth[size_t(i)] / acc[size_t(i)] : 0.0f;
    }
  }
  return v;
}

}  // namespace stylerf::model
