// safetensors files (https://github.com/huggingface/safetensors format): an 8-byte little-endian header
// length, a JSON header {name: {dtype, shape, data_offsets: [begin, end]}, "__metadata__": {...}}, then the
// raw little-endian tensor bytes. We read F32, F16, BF16 and F64 (converted to float) and write F32.
//
// Every error names the file and what is wrong with it, so a user can tell a missing download from a
// corrupt one.
#pragma once
#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace stylerf::io {

// A float tensor in host memory, row-major.
struct HostTensor {
  std::vector<int64_t> shape;
  std::vector<float> data;
};

class SafeTensors {
 public:
  // Reads and validates the whole file. `missing_hint` is appended to the error when the file does not
  // exist (e.g. the command that creates it).
  static SafeTensors load(const std::string& path, const std::string& missing_hint = "");

  const std::string& path() const { return path_; }
  bool has(const std::string& name) const { return tensors_.count(name) != 0; }
  std::vector<std::string> names() const;
  const std::map<std::string, std::string>& metadata() const { return metadata_; }

  // The tensor, or an Error naming the file and the tensor.
  const HostTensor& get(const std::string& name) const;
  // Same, and checks its shape: "<file>: tensor <name> has shape [..], expected [..]".
  const HostTensor& get(const std::string& name, const std::vector<int64_t>& expected_shape) const;

 private:
  std::string path_;
  std::map<std::string, HostTensor> tensors_;
  std::map<std::string, std::string> metadata_;
};

// Writes tensors as F32, atomically (temporary file beside it, then rename). Data is 8-byte aligned.
void save_safetensors(const std::string& path, const std::map<std::string, HostTensor>& tensors,
                      const std::map<std::string, std::string>& metadata = {});

}  // namespace stylerf::io
