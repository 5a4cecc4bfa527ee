// Checkpoints: a safetensors file (lib/io/safetensors.hpp) whose metadata carries
//   "stylerf.format"   = "stylerf-checkpoint"
//   "stylerf.version"  = kCheckpointVersion (files of another version are refused with a clear error)
//   "stylerf.kind"     = what the file holds ("density", later "feature", "style")
//   "stylerf.meta"     = a JSON document of the stage's own settings (config, scene, iteration, ...)
//   "stylerf.checksum" = FNV-1a 64 over every tensor's name, shape and bytes (catches flipped or truncated
//                        data that the safetensors header alone would not notice)
// Written atomically (temporary file + rename): an error or a crash never leaves a half-written checkpoint.
#pragma once
#include <map>
#include <nlohmann/json.hpp>
#include <string>

#include "host/tensor.hpp"
#include "lib/io/safetensors.hpp"

namespace stylerf::io {

constexpr int kCheckpointVersion = 1;

struct Checkpoint {
  std::string kind;
  nlohmann::json meta = nlohmann::json::object();
  std::map<std::string, HostTensor> tensors;
  std::string path;  // set by load_checkpoint (for error messages)

  // The tensor, or an Error naming the file and the tensor (and the shapes when they differ).
  const HostTensor& get(const std::string& name) const;
  const HostTensor& get(const std::string& name, const std::vector<int64_t>& shape) const;
  // Device tensor helpers.
  void put(const std::string& name, const host::Tensor& t);
  host::Tensor device(const std::string& name, const std::vector<int64_t>& shape) const;
};

void save_checkpoint(const std::string& path, const Checkpoint& ck);
// Throws host::Error naming the file when it is missing, not a safetensors file, not a stylerf checkpoint,
// of another version or kind (expected_kind "" accepts any; ck.kind says which), or fails its checksum.
Checkpoint load_checkpoint(const std::string& path, const std::string& expected_kind);

}  // namespace stylerf::io
