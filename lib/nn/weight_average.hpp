// An exponential moving average of named parameters (Polyak averaging), kept beside an optimiser.
//
// Why: the style stage sees one style image a step, so the weights at any one step carry the pull of the
// last few styles (the held-out loss jumps by +-15 between evaluations 100 steps apart on fern). The
// average over the last ~1/(1 - decay) steps is a better model to use than the last iterate.
//
// After each optimiser step, update() moves every average towards its parameter:
//   avg = d_t * avg + (1 - d_t) * value,  d_t = min(decay, (1 + t) / (10 + t)),  t = updates before this one,
// the ramp (TensorFlow's num_updates rule) so that early averages are not dominated by the initial weights.
// A parameter seen for the first time starts its average at its value.
//
// Checkpoints: a trainer swaps the averages in to save the model (so every consumer of the checkpoint
// uses them), swaps back, and save() stores the training values (the last iterate) for --resume; load()
// undoes that: the model's loaded weights become the averages, the stored training values the params.
#pragma once
#include <map>
#include <string>
#include <vector>

#include "lib/nn/module.hpp"

namespace stylerf::io {
struct Checkpoint;
}

namespace stylerf::nn {

class WeightAverage {
 public:
  WeightAverage() = default;
  explicit WeightAverage(float decay);  // decay in [0, 1); 0: off (update and swap do nothing)

  bool enabled() const { return decay_ > 0; }
  int updates() const { return updates_; }
  // The decay the next update() uses.
  float next_decay() const;

  void update(const std::vector<Param*>& params);
  // Exchanges each param's value with its average (a handle swap, no copy); calling it twice restores.
  void swap(const std::vector<Param*>& params);
  // The average of `name` (undefined Tensor if none).
  Tensor average(const std::string& name) const;

  // Stores the params' current values (call with the training values in place) as "<prefix>ema.raw.<name>"
  // and the update count.
  void save(io::Checkpoint& ck, const std::string& prefix, const std::vector<Param*>& params) const;
  // The params' current values (the checkpoint's model weights) become the averages; the stored training
  // values are copied into the params. A checkpoint without them is an Error naming it.
  void load(const io::Checkpoint& ck, const std::string& prefix, const std::vector<Param*>& params);

 private:
  float decay_ = 0;
  int updates_ = 0;
  std::map<std::string, Tensor> avg_;
};

// Swaps the averages in for a scope (evaluation, saving) and back out at its end.
class AveragedWeightsScope {
 public:
  AveragedWeightsScope(WeightAverage& avg, std::vector<Param*> params) : avg_(avg), params_(std::move(params)) {
    avg_.swap(params_);
  }
  ~AveragedWeightsScope() { avg_.swap(params_); }
  AveragedWeightsScope(const AveragedWeightsScope&) = delete;
  AveragedWeightsScope& operator=(const AveragedWeightsScope&) = delete;

 private:
  WeightAverage& avg_;
  std::vector<Param*> params_;
};

}  // namespace stylerf::nn
