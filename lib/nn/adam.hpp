// Adam over named parameters with per-group learning rates (nn/module.hpp's convention).
//
// State (the two moments) is keyed by parameter name, so a model may add parameters later (stage 3 adds
// a stylizer to a stage-2 model) and checkpoints stay readable. remap() carries a parameter's moments
// through a change of its shape (a grid cropped or upsampled); reset() drops them (TensoRF rebuilds its
// optimiser at upsampling). Each parameter counts its own updates for the bias correction (as PyTorch's
// Adam does), so a parameter added or first given a gradient later starts its correction at 1.
#pragma once
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "lib/nn/module.hpp"

namespace stylerf::io {
struct Checkpoint;
}

namespace stylerf::nn {

struct AdamGroup {
  std::string name;  // "grid", "network", ...
  float lr = 1e-3f;
};

class Adam {
 public:
  Adam() = default;
  Adam(std::vector<AdamGroup> groups, float beta1 = 0.9f, float beta2 = 0.999f, float eps = 1e-8f);

  // One step over params (each with a defined grad) at lr = group lr * lr_scale. Parameters without a
  // gradient are skipped; a param whose group does not exist is an Error.
  void step(const std::vector<Param*>& params, float lr_scale = 1.0f);
  int steps() const { return step_; }  // step() calls since construction or reset()
  int updates(const std::string& name) const;  // updates of one parameter (its bias-correction clock; 0: none)

  // Moments of `name` become f(moment) (f maps a tensor shaped like the old parameter to one shaped like
  // the new one). No-op for a parameter without state.
  void remap(const std::string& name, const std::function<Tensor(const Tensor&)>& f);
  void reset();                        // all moments and the step count
  void reset(const std::string& name); // one parameter's moments

  std::vector<AdamGroup>& groups() { return groups_; }
  const std::vector<AdamGroup>& groups() const { return groups_; }

  void save(io::Checkpoint& ck, const std::string& prefix) const;
  // Restores moments for the given params (shapes checked) and the step count; params absent from the
  // checkpoint start with zero moments.
  void load(const io::Checkpoint& ck, const std::string& prefix, const std::vector<Param*>& params);

 private:
  struct Moments {
    Tensor m, v;
    int steps = 0;  // updates of this parameter (its bias correction), as PyTorch keeps per parameter
  };
  std::vector<AdamGroup> groups_;
  float beta1_ = 0.9f, beta2_ = 0.999f, eps_ = 1e-8f;
  int step_ = 0;
  std::map<std::string, Moments> state_;
};

}  // namespace stylerf::nn
