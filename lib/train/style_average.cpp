#include "lib/train/style_average.hpp"

#include <filesystem>
#include <map>

#include "host/error.hpp"
#include "lib/model/style_model.hpp"

namespace stylerf::train {

using host::Error;
using nlohmann::json;

namespace {

// Optimiser and weight-average state: meaningless for an average, and dropped from it.
bool trainer_state(const std::string& name) { return name.rfind("adam.", 0) == 0 || name.rfind("ema.raw.", 0) == 0; }

void strip_trainer_state(io::Checkpoint& ck) {
  for (auto it = ck.tensors.begin(); it != ck.tensors.end();)
    it = trainer_state(it->first) ? ck.tensors.erase(it) : std::next(it);
  for (const char* key : {"adam", "ema", "trainer"}) ck.meta.erase(key);
}

// The metadata that says which run a checkpoint belongs to; inputs must agree on all of it.
constexpr const char* kRunMeta[] = {"styles", "style_model", "feature_model", "scene"};

// An input is a checkpoint `train-style` wrote: its trainer state says its run and iteration.
void check_trainer_written(const io::Checkpoint& ck, const std::string& path) {
  if (ck.meta.contains("averaged"))
    throw Error("average-style: " + path + " is itself an average; average the snapshots it was made of");
  if (!ck.meta.contains("trainer"))
    throw Error("average-style: " + path + " has no trainer state (its run and iteration); pass checkpoints that "
                "`train-style` wrote");
}

// The trainer's configuration but its step count, which a time-budgeted run refits as it goes.
json run_config(const io::Checkpoint& ck) {
  json c = ck.meta.at("trainer").value("config", json::object());
  c.erase("iters");
  return c;
}

}  // namespace

io::Checkpoint average_style_checkpoints(const std::vector<std::string>& paths) {
  if (paths.size() < 2)
    throw Error("average-style: needs two or more style checkpoints of one run, got " + std::to_string(paths.size()));
  // The last input is the template: its metadata and frozen tensors are the result's.
  io::Checkpoint out = io::load_checkpoint(paths.back(), "style");
  check_trainer_written(out, paths.back());
  std::map<std::string, std::vector<double>> sums;  // the averaged tensors, by checkpoint name
  {
    model::StyleModel m = model::StyleModel::load(out);
    io::Checkpoint trained;
    m.save_trained(trained);
    for (const auto& [name, t] : trained.tensors) sums[name].assign(t.data.size(), 0.0);
  }
  json from = json::array();
  for (size_t i = 0; i < paths.size(); ++i) {
    const bool last = i + 1 == paths.size();
    io::Checkpoint loaded;
    if (!last) loaded = io::load_checkpoint(paths[i], "style");
    const io::Checkpoint& ck = last ? out : loaded;
    check_trainer_written(ck, paths[i]);
    if (run_config(ck) != run_config(out))
      throw Error("average-style: " + paths[i] + " was trained with another configuration (seed, rates, ...) than " +
                  paths.back() + ": the checkpoints are not of one run");
    for (const char* key : kRunMeta)
      if (ck.meta.value(key, json()) != out.meta.value(key, json()))
        throw Error("average-style: " + paths[i] + "'s '" + key + "' differs from " + paths.back() +
                    "'s: the checkpoints are not of one run");
    for (const auto& [name, t] : out.tensors) {
      if (trainer_state(name)) continue;
      const auto it = ck.tensors.find(name);
      if (it == ck.tensors.end()) throw Error("average-style: " + paths[i] + " has no tensor '" + name + "'");
      if (it->second.shape != t.shape)
        throw Error("average-style: " + paths[i] + ": tensor '" + name + "' has shape " + host::shape_str(it->second.shape) +
                    ", " + paths.back() + "'s has " + host::shape_str(t.shape));
      auto sum = sums.find(name);
      if (sum != sums.end()) {
        for (size_t k = 0; k < t.data.size(); ++k) sum->second[k] += double(it->second.data[k]);
      } else if (!last && it->second.data != t.data) {
        throw Error("average-style: " + paths[i] + ": frozen tensor '" + name + "' differs from " + paths.back() +
                    "'s: the checkpoints are not of one run over one feature checkpoint");
      }
    }
    from.push_back({{"path", paths[i]}, {"iteration", ck.meta.at("trainer").value("iteration", -1)}});
  }
  const double n = double(paths.size());
  for (const auto& [name, sum] : sums) {
    std::vector<float>& dst = out.tensors.at(name).data;
    for (size_t k = 0; k < dst.size(); ++k) dst[k] = float(sum[k] / n);
  }
  strip_trainer_state(out);
  out.meta["averaged"] = {{"from", from}};
  out.path.clear();
  return out;
}

std::string snapshot_path(const std::string& path, int iteration) {
  const std::filesystem::path p(path);
  const std::string name = p.stem().string() + ".it" + std::to_string(iteration) + p.extension().string();
  return (p.parent_path() / name).string();
}

}  // namespace stylerf::train
