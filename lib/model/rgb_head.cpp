#include "lib/model/rgb_head.hpp"

#include "host/error.hpp"
#include "lib/render/deferred.hpp"

namespace stylerf::model {

using host::Error;

static const char* kMlpNames[] = {"basis", "w1", "b1", "w2", "b2", "w3", "b3"};

struct RgbContext : SampleHead::Context {
  Tensor pos;
  field::HeadCache mlp;
};

RgbHead::RgbHead(field::VMGrid app, const field::AppearanceHead& mlp, bool deferred)
    : res_(app.res), rank_(app.rank), cfg_(mlp.cfg), app_("app", 0, app.params), deferred_(deferred) {
  const Tensor* t[7] = {&mlp.basis, &mlp.w1, &mlp.b1, &mlp.w2, &mlp.b2, &mlp.w3, &mlp.b3};
  for (int i = 0; i < 7; ++i) mlp_[i] = nn::Param(std::string("head.") + kMlpNames[i], 1, *t[i]);
}

field::AppearanceHead RgbHead::mlp() const {
  field::AppearanceHead h;
  h.cfg = cfg_;
  Tensor* t[7] = {&h.basis, &h.w1, &h.b1, &h.w2, &h.b2, &h.w3, &h.b3};
  for (int i = 0; i < 7; ++i) *t[i] = mlp_[i].value;
  return h;
}

void RgbHead::set_app(const field::VMGrid& g) {
  res_ = g.res;
  rank_ = g.rank;
  app_.value = g.params;
  app_.grad = Tensor();
}

Tensor RgbHead::forward(const Tensor& pos, const Tensor& dirs, std::unique_ptr<Context>* ctx) const {
  Tensor feat = field::features_forward(app(), pos);
  if (deferred_) {
    if (ctx) {
      auto c = std::make_unique<RgbContext>();
      c->pos = pos;
      *ctx = std::move(c);
    }
    return feat;
  }
  if (!ctx) return field::appearance_forward(mlp(), feat, dirs, nullptr);
  auto c = std::make_unique<RgbContext>();
  c->pos = pos;
  Tensor rgb = field::appearance_forward(mlp(), feat, dirs, &c->mlp);
  *ctx = std::move(c);
  return rgb;
}

void RgbHead::backward(const Context& ctx, const Tensor& dvalues) {
  const auto& c = static_cast<const RgbContext&>(ctx);
  if (deferred_) {
    field::features_backward(app(), c.pos, dvalues, app_.grad_buffer());
    return;
  }
  field::HeadGrads g = field::appearance_backward(mlp(), c.mlp, dvalues);
  auto gp = g.params();
  for (int i = 0; i < 7; ++i) mlp_[i].accumulate(*gp[size_t(i)]);
  field::features_backward(app(), c.pos, g.dfeat, app_.grad_buffer());
}

struct ShadeContext : SampleHead::Context {
  Tensor F, a, c;
  field::HeadCache mlp;
};

Tensor RgbHead::shade(const Tensor& F, const Tensor& kept_acc, const Tensor& dirs, std::unique_ptr<Context>* ctx) const {
  if (!deferred_) throw Error("RgbHead::shade: this head shades per sample");
  const Tensor n = render::opacity_normalise_forward(F, kept_acc);
  if (!ctx) return render::opacity_scale_forward(field::appearance_forward(mlp(), n, dirs, nullptr), kept_acc);
  auto c = std::make_unique<ShadeContext>();
  c->F = F;
  c->a = kept_acc;
  c->c = field::appearance_forward(mlp(), n, dirs, &c->mlp);
  Tensor rgb = render::opacity_scale_forward(c->c, kept_acc);
  *ctx = std::move(c);
  return rgb;
}

Tensor RgbHead::shade_backward(const Context& ctx, const Tensor& drgb, Tensor& dkept_acc) {
  const auto& c = static_cast<const ShadeContext&>(ctx);
  dkept_acc = Tensor::zeros(c.a.shape(), "d kept opacity");
  const Tensor dc = render::opacity_scale_backward(c.c, c.a, drgb, dkept_acc);
  field::HeadGrads g = field::appearance_backward(mlp(), c.mlp, dc);
  auto gp = g.params();
  for (int i = 0; i < 7; ++i) mlp_[i].accumulate(*gp[size_t(i)]);
  return render::opacity_normalise_backward(c.F, c.a, g.dfeat, dkept_acc);
}

void RgbHead::collect_params(std::vector<nn::Param*>& out) {
  out.push_back(&app_);
  for (auto& p : mlp_) out.push_back(&p);
}

}  // namespace stylerf::model
