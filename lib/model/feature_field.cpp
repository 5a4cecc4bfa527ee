#include "lib/model/feature_field.hpp"

#include <cmath>
#include <random>

#include "host/error.hpp"
#include "host/gemm.hpp"
#include "lib/nn/ops.hpp"
#include "lib/render/composite_values.hpp"
#include "lib/scene/rays.hpp"

namespace stylerf::model {

using host::Error;
using host::Trans;

struct FeatureGridContext : SampleHead::Context {
  Tensor pos;
};

Tensor FeatureGridHead::forward(const Tensor& pos, const Tensor& dirs, std::unique_ptr<Context>* ctx) const {
  if (ctx) {
    auto c = std::make_unique<FeatureGridContext>();
    c->pos = pos;
    *ctx = std::move(c);
  }
  return field::features_forward(grid(), pos);
}

void FeatureGridHead::backward(const Context& ctx, const Tensor& dvalues) {
  const auto& c = static_cast<const FeatureGridContext&>(ctx);
  field::features_backward(grid(), c.pos, dvalues, grid_.grad_buffer());
}

FeatureField FeatureField::create(const Geometry& g, const FeatureFieldConfig& cfg, uint64_t seed) {
  FeatureField f;
  f.cfg = cfg;
  f.head = FeatureGridHead(field::VMGrid::create(g.res(), cfg.rank, cfg.init_scale, seed * 2 + 1));
  const int F = f.head.channels();
  std::mt19937_64 rng(seed * 2 + 2);
  const float bound = 1.0f / std::sqrt(float(F));
  std::uniform_real_distribution<float> u(-bound, bound);
  std::vector<float> b(size_t(F) * cfg.channels);
  for (auto& x : b) x = u(rng);
  f.basis.value = Tensor::from_host(b, {F, cfg.channels}, "feature basis");
  if (g.has_background) f.background.value = Tensor::zeros({cfg.channels}, "feature background");
  if (g.shell.on()) f.shell.value = Tensor::zeros({g.shell.texels(), cfg.channels}, "feature shell");
  return f;
}

RayResult FeatureField::render(const Geometry& g, const Tensor& origins, const Tensor& dirs, const RayOptions& opt,
                               Context* ctx) const {
  RayResult r = render_rays(g, head, origins, dirs, opt, ctx ? &ctx->rays : nullptr);
  Tensor feat({r.value.dim(0), cfg.channels}, "rendered features");
  if (feat.numel() > 0) host::matmul(r.value, Trans::No, basis.value, Trans::No, feat);
  if (background.value.defined() && feat.numel() > 0) render::background_forward(feat, r.acc, background.value);
  render::ShellTaps taps;
  if (shell.value.defined() && feat.numel() > 0) {
    taps = g.shell_taps(origins, dirs);
    render::background_shell_forward(feat, r.acc, shell.value, taps);
  }
  if (ctx) ctx->composited = r.value, ctx->rays_acc = r.acc, ctx->shell_taps = std::move(taps);
  r.value = feat;
  return r;
}

void FeatureField::render_backward(const Geometry& g, const Context& ctx, const Tensor& dfeat,
                                   const Tensor& dkept_acc) {
  Tensor dcomp;
  if (dfeat.defined()) {
    host::expect_shape(dfeat, {ctx.composited.dim(0), cfg.channels}, "FeatureField::render_backward", "dfeat");
    // basis grad += composited^T dfeat; d composited = dfeat basis^T.
    Tensor& db = basis.grad_buffer();
    if (dfeat.numel() > 0) host::matmul(ctx.composited, Trans::Yes, dfeat, Trans::No, db, 1.0f, 1.0f);
    dcomp = Tensor(ctx.composited.shape(), "d composited grid features");
    if (dcomp.numel() > 0) host::matmul(dfeat, Trans::No, basis.value, Trans::Yes, dcomp);
    if (background.value.defined() && dfeat.numel() > 0) {
      // d background = sum_r (1 - acc_r) dfeat_r: a [1, R] x [R, C] product. (The opacity is the
      // frozen geometry's: no gradient flows to it.)
      const int64_t R = dfeat.dim(0);
      Tensor transparency = Tensor::full({1, R}, 1.0f, "ray transparency");
      nn::axpby(-1.0f, ctx.rays_acc.reshape({1, R}), 1.0f, transparency);
      Tensor dbg = background.grad_buffer().reshape({1, cfg.channels});
      host::matmul(transparency, Trans::No, dfeat, Trans::No, dbg, 1.0f, 1.0f);
    }
    if (shell.value.defined() && dfeat.numel() > 0)
      render::background_shell_backward(dfeat, ctx.rays_acc, shell.value, ctx.shell_taps, nullptr, false,
                                        &shell.grad_buffer());
  }
  render_rays_backward(g, head, ctx.rays, dcomp, dkept_acc, nullptr);
}

// Per point: the basis inside the head (grid features x basis for every kept sample).
namespace {
class PerPointHead : public SampleHead {
 public:
  PerPointHead(const FeatureGridHead& grid, const Tensor& basis) : grid_(grid), basis_(basis) {}
  int channels() const override { return int(basis_.dim(1)); }
  Tensor forward(const Tensor& pos, const Tensor& dirs, std::unique_ptr<Context>*) const override {
    Tensor f = grid_.forward(pos, dirs, nullptr);
    Tensor out({f.dim(0), basis_.dim(1)}, "per-point features");
    host::matmul(f, Trans::No, basis_, Trans::No, out);
    return out;
  }
  void backward(const Context&, const Tensor&) override { throw Error("per-point feature head: inference only"); }
  void collect_params(std::vector<nn::Param*>&) override {}

 private:
  const FeatureGridHead& grid_;
  Tensor basis_;
};
}  // namespace

RayResult FeatureField::render_per_point(const Geometry& g, const Tensor& origins, const Tensor& dirs,
                                         const RayOptions& opt) const {
  PerPointHead h(head, basis.value);
  RayResult r = render_rays(g, h, origins, dirs, opt, nullptr);
  if (background.value.defined() && r.value.numel() > 0) render::background_forward(r.value, r.acc, background.value);
  if (shell.value.defined() && r.value.numel() > 0)
    render::background_shell_forward(r.value, r.acc, shell.value, g.shell_taps(origins, dirs));
  return r;
}

Tensor FeatureField::shell_term(const Geometry& g, const Tensor& origins, const Tensor& dirs, const Tensor& acc) const {
  if (!shell.value.defined()) return Tensor();
  Tensor out = Tensor::zeros({acc.numel(), cfg.channels}, "shell term");
  if (acc.numel() > 0) render::background_shell_forward(out, acc, shell.value, g.shell_taps(origins, dirs));
  return out;
}

void FeatureField::collect_params(std::vector<nn::Param*>& out) {
  head.collect_params(out);
  out.push_back(&basis);
  if (background.value.defined()) out.push_back(&background);
  if (shell.value.defined()) out.push_back(&shell);
}

}  // namespace stylerf::model
