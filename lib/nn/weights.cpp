#include "lib/nn/weights.hpp"

#include <cstdlib>

namespace stylerf::nn {

std::string weights_dir() {
  if (const char* d = std::getenv("STYLERF_WEIGHTS"); d && *d) return d;
  const char* home = std::getenv("HOME");
  return std::string(home && *home ? home : ".") + "/.cache/stylerf/weights";
}

std::string weights_path(const std::string& file) {
  return file.find('/') != std::string::npos ? file : weights_dir() + "/" + file;
}

io::SafeTensors load_weights(const std::string& path) {
  return io::SafeTensors::load(path, std::string("run `") + kFetchWeightsCommand +
                                         "` to download and convert the pretrained weights (into $STYLERF_WEIGHTS, "
                                         "default ~/.cache/stylerf/weights)");
}

}  // namespace stylerf::nn
