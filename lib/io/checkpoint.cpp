#include "lib/io/checkpoint.hpp"

#include <cstdio>
#include <cstring>
#include <filesystem>

#include "host/error.hpp"

namespace stylerf::io {

using host::Error;

static const char* kFormat = "stylerf-checkpoint";

static std::string checksum(const std::map<std::string, HostTensor>& tensors) {
  uint64_t h = 1469598103934665603ULL;
  auto mix = [&h](const void* p, size_t n) {
    const auto* b = static_cast<const unsigned char*>(p);
    for (size_t i = 0; i < n; ++i) {
      h ^= b[i];
      h *= 1099511628211ULL;
    }
  };
  for (const auto& [name, t] : tensors) {  // std::map: sorted, so the order is fixed
    mix(name.data(), name.size());
    for (int64_t d : t.shape) mix(&d, sizeof d);
    mix(t.data.data(), t.data.size() * sizeof(float));
  }
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h));
  return buf;
}

const HostTensor& Checkpoint::get(const std::string& name) const {
  auto it = tensors.find(name);
  if (it == tensors.end()) throw Error("checkpoint " + path + ": no tensor named '" + name + "'");
  return it->second;
}

const HostTensor& Checkpoint::get(const std::string& name, const std::vector<int64_t>& shape) const {
  const HostTensor& t = get(name);
  if (t.shape != shape)
    throw Error("checkpoint " + path + ": tensor '" + name + "' has shape " + host::shape_str(t.shape) +
                ", expected " + host::shape_str(shape));
  return t;
}

void Checkpoint::put(const std::string& name, const host::Tensor& t) {
  HostTensor h;
  h.shape = t.shape();
  if (t.numel() > 0) h.data = t.to_host();
  tensors[name] = std::move(h);
}

host::Tensor Checkpoint::device(const std::string& name, const std::vector<int64_t>& shape) const {
  const HostTensor& h = get(name, shape);
  if (h.data.empty()) return host::Tensor(shape, name);
  return host::Tensor::from_host(h.data, shape, name);
}

void save_checkpoint(const std::string& path, const Checkpoint& ck) {
  if (ck.kind.empty()) throw Error("save_checkpoint " + path + ": checkpoint kind is empty");
  std::map<std::string, std::string> md;
  md["stylerf.format"] = kFormat;
  md["stylerf.version"] = std::to_string(kCheckpointVersion);
  md["stylerf.kind"] = ck.kind;
  md["stylerf.meta"] = ck.meta.dump();
  md["stylerf.checksum"] = checksum(ck.tensors);
  save_safetensors(path, ck.tensors, md);
}

Checkpoint load_checkpoint(const std::string& path, const std::string& expected_kind) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec))
    throw Error("checkpoint " + path + " is a folder, not a checkpoint file");
  if (!std::filesystem::is_regular_file(path, ec))
    throw Error("checkpoint " + path + " does not exist" +
                (expected_kind.empty() ? std::string() : " (train one with `stylerf train-" + expected_kind + "`)"));
  SafeTensors st;
  try {
    st = SafeTensors::load(path);
  } catch (const Error& e) {
    throw Error("checkpoint " + path + " is not a readable stylerf checkpoint: " + e.what());
  }
  const auto& md = st.metadata();
  auto field = [&](const char* key) -> std::string {
    auto it = md.find(key);
    return it == md.end() ? std::string() : it->second;
  };
  if (field("stylerf.format") != kFormat)
    throw Error("checkpoint " + path + " is a safetensors file but not a stylerf checkpoint (no stylerf.format)");
  if (field("stylerf.version") != std::to_string(kCheckpointVersion))
    throw Error("checkpoint " + path + " has version '" + field("stylerf.version") + "'; this build reads version " +
                std::to_string(kCheckpointVersion));
  Checkpoint ck;
  ck.path = path;
  ck.kind = field("stylerf.kind");
  if (!expected_kind.empty() && ck.kind != expected_kind)
    throw Error("checkpoint " + path + " holds a '" + ck.kind + "' stage, expected '" + expected_kind + "'");
  try {
    ck.meta = nlohmann::json::parse(field("stylerf.meta"));
  } catch (const std::exception& e) {
    throw Error("checkpoint " + path + ": corrupt metadata (" + e.what() + ")");
  }
  for (const auto& name : st.names()) ck.tensors[name] = st.get(name);
  const std::string want = field("stylerf.checksum"), got = checksum(ck.tensors);
  if (want != got)
    throw Error("checkpoint " + path + " is corrupt: checksum " + got + " does not match the stored " + want);
  return ck;
}

}  // namespace stylerf::io
