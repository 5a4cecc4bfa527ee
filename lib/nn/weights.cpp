#include "lib/nn/weights.hpp"

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "host/error.hpp"
#include "host/files.hpp"
#include "lib/io/sha256.hpp"

namespace stylerf::nn {

std::string weights_dir() {
  if (const char* d = std::getenv("STYLERF_WEIGHTS"); d && *d) return d;
  const char* home = std::getenv("HOME");
  return std::string(home && *home ? home : ".") + "/.cache/stylerf/weights";
}

std::string weights_path(const std::string& file) {
  return file.find('/') != std::string::npos ? file : weights_dir() + "/" + file;
}

namespace {
// When manifest.json beside the file lists it, its sha256 must match. Verified once per file version: a
// stamp beside it records the size, time and sum it was verified at (hashing 80 MB takes a moment).
void check_manifest(const std::string& path) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path file(path);
  const fs::path manifest = file.parent_path() / "manifest.json";
  if (!fs::exists(manifest, ec) || !fs::exists(file, ec)) return;
  std::string want;
  try {
    const auto j = nlohmann::json::parse(host::read_file(manifest.string()));
    const std::string name = file.filename().string();
    if (!j.contains("files") || !j["files"].contains(name)) return;
    want = j["files"][name].value("sha256", "");
  } catch (const nlohmann::json::exception& e) {
    throw host::Error(manifest.string() + " is not valid JSON (" + e.what() + "); rerun `" + kFetchWeightsCommand + "`");
  }
  if (want.empty()) return;
  const auto size = fs::file_size(file, ec);
  const auto time = fs::last_write_time(file, ec).time_since_epoch().count();
  const std::string stamp_text = std::to_string(size) + " " + std::to_string(time) + " " + want;
  const fs::path stamp = file.parent_path() / ("." + file.filename().string() + ".verified");
  {
    std::ifstream f(stamp);
    std::string line;
    if (f && std::getline(f, line) && line == stamp_text) return;
  }
  const std::string got = io::sha256_file(path);
  if (got != want)
    throw host::Error(path + ": sha256 " + got + " differs from " + want + " recorded in " + manifest.string() +
                      "; the file is damaged or was replaced: rerun `" + kFetchWeightsCommand + "`");
  try {
    host::write_file_atomic(stamp.string(), stamp_text + "\n");
  } catch (const host::Error&) {
    // A read-only weights folder: verify again next time.
  }
}
}  // namespace

io::SafeTensors load_weights(const std::string& path) {
  check_manifest(path);
  io::SafeTensors st = io::SafeTensors::load(path, std::string("run `") + kFetchWeightsCommand +
                                                       "` to download and convert the pretrained weights (into "
                                                       "$STYLERF_WEIGHTS, default ~/.cache/stylerf/weights)");
  // NaN or infinite weights would give a flat grey image and exit 0: refuse them, naming the tensor.
  for (const std::string& name : st.names()) {
    const auto& v = st.get(name).data;
    for (size_t i = 0; i < v.size(); ++i)
      if (!std::isfinite(v[i]))
        throw host::Error(path + ": tensor " + name + " has a non-finite value at element " + std::to_string(i) +
                          "; the weights are damaged: rerun `" + kFetchWeightsCommand + "`");
  }
  return st;
}

}  // namespace stylerf::nn
