// Where pretrained weights live and how a missing set-up is reported.
//
// Weights are created by the set-up command `bash scripts/fetch_weights.sh`, which downloads AdaIN's VGG-19
// and decoder and converts them to safetensors in the weights folder: $STYLERF_WEIGHTS when set, else
// ~/.cache/stylerf/weights (the same rule the script uses).
#pragma once
#include <string>

#include "lib/io/safetensors.hpp"

namespace stylerf::nn {

constexpr const char* kFetchWeightsCommand = "bash scripts/fetch_weights.sh";
constexpr const char* kVggWeightsFile = "vgg_normalised.safetensors";
constexpr const char* kDecoderWeightsFile = "adain_decoder.safetensors";

std::string weights_dir();
// weights_dir()/file, or `file` itself when it contains a '/' (an explicit path).
std::string weights_path(const std::string& file);

// Loads a weights file; when it is missing the error names the path and the set-up command. The file must
// match the sha256 its folder's manifest.json records (when it lists it), and every value must be finite.
io::SafeTensors load_weights(const std::string& path);

}  // namespace stylerf::nn
