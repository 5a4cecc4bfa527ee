// The target cache's file (target_cache.hpp): a safetensors file with one tensor, "targets" [V, Hf, Wf, 256]
// in F16 or F32, written and read one view at a time, so neither side holds more than a view on the host
// (lego at 800x800: 2 GB of maps on the device, 41 MB of host buffers).
//
// Metadata: "stylerf.format" = "stylerf-feature-targets", "stylerf.meta" = a JSON document (the cache key,
// the scene, the convention) and "stylerf.checksum" = FNV-1a 64 over the data bytes, as 16 hex digits (byte by byte,
// so it does not depend on how the data was cut into appends; ContentHash would). The
// checksum is written last, over a placeholder of the same width, then the file is renamed into place
// (host::write_atomic_with): a killed writer leaves no file under the real name.
#pragma once
#include <cstdint>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "lib/features/feature_targets.hpp"

namespace stylerf::features {

class TargetFileWriter {
 public:
  // Opens `tmp_path` and writes the header of maps of this dtype (F16 or F32) and shape [V, Hf, Wf, C].
  TargetFileWriter(const std::string& tmp_path, host::DType dtype, const host::Shape& shape, const nlohmann::json& meta);
  void append(const std::vector<uint8_t>& view_bytes);  // the next view's bytes
  void finish();  // checks every view came, writes the checksum, closes; throws host::Error on any failure

 private:
  std::string path_;
  std::ofstream out_;
  uint64_t expected_ = 0, written_ = 0, hash_ = 0;
  std::streamoff checksum_at_ = 0;
};

// Reads the file into `targets` (allocated with the shape and dtype expected), view by view, and returns
// its metadata's "stylerf.meta". Throws host::Error naming the file and what is wrong: not a target file,
// another shape or dtype, truncated, or a checksum that does not match (the maps are then partly written:
// the caller recomputes them).
nlohmann::json read_target_file(const std::string& path, FeatureTargets& targets);

}  // namespace stylerf::features
