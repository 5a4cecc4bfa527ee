#include "lib/nn/adam.hpp"

#include "host/error.hpp"
#include "lib/io/checkpoint.hpp"
#include "lib/nn/ops.hpp"

namespace stylerf::nn {

using host::Error;

Adam::Adam(std::vector<AdamGroup> groups, float beta1, float beta2, float eps)
    : groups_(std::move(groups)), beta1_(beta1), beta2_(beta2), eps_(eps) {
  if (groups_.empty()) throw Error("Adam: no parameter groups");
}

void Adam::step(const std::vector<Param*>& params, float lr_scale) {
  ++step_;
  for (Param* p : params) {
    if (!p->grad.defined()) continue;
    if (p->group < 0 || p->group >= int(groups_.size()))
      throw Error("Adam: parameter " + p->name + " is in group " + std::to_string(p->group) + ", optimiser has " +
                  std::to_string(groups_.size()) + " groups");
    auto it = state_.find(p->name);
    if (it == state_.end() || it->second.m.numel() != p->value.numel()) {
      // A parameter seen for the first time (or whose shape changed without a remap) starts from zero.
      Moments mo{Tensor::zeros(p->value.shape(), "Adam m of " + p->name),
                 Tensor::zeros(p->value.shape(), "Adam v of " + p->name), 0};
      it = state_.insert_or_assign(p->name, mo).first;
    }
    AdamConfig c;
    c.lr = groups_[size_t(p->group)].lr * lr_scale;
    c.beta1 = beta1_;
    c.beta2 = beta2_;
    c.eps = eps_;
    Tensor g = p->grad.reshape(p->value.shape());
    Tensor m = it->second.m.reshape(p->value.shape()), v = it->second.v.reshape(p->value.shape());
    adam_step(p->value, g, m, v, ++it->second.steps, c);
  }
}

int Adam::updates(const std::string& name) const {
  const auto it = state_.find(name);
  return it == state_.end() ? 0 : it->second.steps;
}

void Adam::remap(const std::string& name, const std::function<Tensor(const Tensor&)>& f) {
  auto it = state_.find(name);
  if (it == state_.end()) return;
  it->second.m = f(it->second.m);
  it->second.v = f(it->second.v);
}

void Adam::reset() {
  state_.clear();
  step_ = 0;
}

void Adam::reset(const std::string& name) { state_.erase(name); }

void Adam::save(io::Checkpoint& ck, const std::string& prefix) const {
  nlohmann::json groups = nlohmann::json::array();
  for (const auto& g : groups_) groups.push_back({{"name", g.name}, {"lr", g.lr}});
  ck.meta[prefix + "adam"] = {{"step", step_}, {"beta1", beta1_}, {"beta2", beta2_}, {"eps", eps_}, {"groups", groups}};
  nlohmann::json steps = nlohmann::json::object();
  for (const auto& [name, mo] : state_) {
    ck.put(prefix + "adam.m." + name, mo.m);
    ck.put(prefix + "adam.v." + name, mo.v);
    steps[name] = mo.steps;
  }
  ck.meta[prefix + "adam"]["param_steps"] = steps;
}

void Adam::load(const io::Checkpoint& ck, const std::string& prefix, const std::vector<Param*>& params) {
  const std::string key = prefix + "adam";
  if (!ck.meta.contains(key)) throw Error("checkpoint " + ck.path + " has no optimiser state (" + key + ")");
  state_.clear();
  try {
    const auto& j = ck.meta.at(key);
    step_ = j.at("step").get<int>();
    for (Param* p : params) {
      const std::string m = prefix + "adam.m." + p->name, v = prefix + "adam.v." + p->name;
      if (!ck.tensors.count(m)) continue;
      state_[p->name] = Moments{ck.device(m, p->value.shape()), ck.device(v, p->value.shape()),
                                j.at("param_steps").at(p->name).get<int>()};
    }
  } catch (const nlohmann::json::exception& e) {
    throw Error("checkpoint " + ck.path + ": bad optimiser metadata (" + e.what() + ")");
  }
}

}  // namespace stylerf::nn
