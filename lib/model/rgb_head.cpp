#include "lib/model/rgb_head.hpp"

namespace stylerf::model {

static const char* kMlpNames[] = {"basis", "w1", "b1", "w2", "b2", "w3", "b3"};

struct RgbContext : SampleHead::Context {
  Tensor pos;
  field::HeadCache mlp;
};

RgbHead::RgbHead(field::VMGrid app, const field::AppearanceHead& mlp)
    : res_(app.res), rank_(app.rank), cfg_(mlp.cfg), app_("app", 0, app.params) {
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
  if (!ctx) return field::appearance_forward(mlp(), feat, dirs, nullptr);
  auto c = std::make_unique<RgbContext>();
  c->pos = pos;
  Tensor rgb = field::appearance_forward(mlp(), feat, dirs, &c->mlp);
  *ctx = std::move(c);
  return rgb;
}

void RgbHead::backward(const Context& ctx, const Tensor& dvalues) {
  const auto& c = static_cast<const RgbContext&>(ctx);
  field::HeadGrads g = field::appearance_backward(mlp(), c.mlp, dvalues);
  auto gp = g.params();
  for (int i = 0; i < 7; ++i) mlp_[i].accumulate(*gp[size_t(i)]);
  field::features_backward(app(), c.pos, g.dfeat, app_.grad_buffer());
}

void RgbHead::collect_params(std::vector<nn::Param*>& out) {
  out.push_back(&app_);
  for (auto& p : mlp_) out.push_back(&p);
}

}  // namespace stylerf::model
