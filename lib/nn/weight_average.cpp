#include "lib/nn/weight_average.hpp"

#include <algorithm>
#include <utility>

#include "host/error.hpp"
#include "lib/io/checkpoint.hpp"
#include "lib/nn/ops.hpp"

namespace stylerf::nn {

using host::Error;

WeightAverage::WeightAverage(float decay) : decay_(decay) {
  if (!(decay >= 0.0f && decay < 1.0f)) throw Error("weight average: decay must be in [0, 1), got " + std::to_string(decay));
}

float WeightAverage::next_decay() const {
  return std::min(decay_, float(1 + updates_) / float(10 + updates_));
}

void WeightAverage::update(const std::vector<Param*>& params) {
  if (!enabled()) return;
  const float d = next_decay();
  for (Param* p : params) {
    auto it = avg_.find(p->name);
    if (it == avg_.end() || it->second.numel() != p->value.numel()) {
      avg_.insert_or_assign(p->name, p->value.clone());
      continue;
    }
    axpby(1.0f - d, p->value, d, it->second);
  }
  ++updates_;
}

void WeightAverage::swap(const std::vector<Param*>& params) {
  if (!enabled()) return;
  for (Param* p : params) {
    auto it = avg_.find(p->name);
    if (it != avg_.end()) std::swap(p->value, it->second);
  }
}

Tensor WeightAverage::average(const std::string& name) const {
  auto it = avg_.find(name);
  return it == avg_.end() ? Tensor() : it->second;
}

void WeightAverage::save(io::Checkpoint& ck, const std::string& prefix, const std::vector<Param*>& params) const {
  if (!enabled()) return;
  ck.meta[prefix + "ema"] = {{"updates", updates_}};  // the decay is its owner's config
  for (const Param* p : params) ck.put(prefix + "ema.raw." + p->name, p->value);
}

void WeightAverage::load(const io::Checkpoint& ck, const std::string& prefix, const std::vector<Param*>& params) {
  if (!enabled()) return;
  const std::string key = prefix + "ema";
  if (!ck.meta.contains(key))
    throw Error("checkpoint " + ck.path + " has no weight-average state (" + key + ") to resume from");
  try {
    updates_ = ck.meta.at(key).at("updates").get<int>();
  } catch (const nlohmann::json::exception& e) {
    throw Error("checkpoint " + ck.path + ": bad weight-average metadata (" + e.what() + ")");
  }
  avg_.clear();
  for (Param* p : params) {
    const std::string raw = prefix + "ema.raw." + p->name;
    if (!ck.tensors.count(raw))
      throw Error("checkpoint " + ck.path + " has no training value of " + p->name + " (" + raw + ")");
    avg_[p->name] = p->value.clone();
    p->value.copy_from(ck.device(raw, p->value.shape()));
  }
}

}  // namespace stylerf::nn
