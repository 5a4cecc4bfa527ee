// The on-disk cache of stage-2 feature targets: computed once per (scene, downsample, weights), then read
// back instead of running VGG over every training view again (lego at 1/4: 100 views, 256 MB; reading it
// back, hashing the inputs and checking the checksum took 2.4 s against 26 s to compute, on the 2-core CPU
// while other jobs ran).
//
// File: <dir>/<key>.safetensors (target_file.hpp: checksummed, streamed a view at a time) holding "targets"
// [V, Hf, Wf, 256] in the maps' dtype and a meta document with the key, the scene and the weights path.
// Written atomically (temporary file + rename).
//
// The key hashes everything the maps depend on:
//  - the convention version of feature_targets.hpp (padding, crop, layer) and the storage dtype;
//  - the scene's root directory and name, the split ("train"), the number of views and their size;
//  - every training view's image path and its pixels as loaded (so the downsample factor, the resize and
//    the background compositing are all covered: a different --downsample gives other pixels);
//  - the VGG weights file's bytes and size.
// A cache file that is unreadable, corrupt (checksum), of another key or shape is recomputed and replaced,
// with a one-line message; it is never trusted because of its name alone.
#pragma once
#include <iosfwd>
#include <string>

#include "lib/features/feature_targets.hpp"

namespace stylerf::features {

struct TargetCacheOptions {
  std::string dir;           // empty: host::cache_dir() + "/targets" ($STYLERF_CACHE_DIR, default ~/.cache/stylerf)
  bool use_cache = true;     // false: compute, neither read nor write the cache
  host::DType dtype = kTargetDType;  // F16 (training's) or F32
  std::ostream* log = nullptr;  // progress and cache decisions (nullptr: silent)
};

// The default cache folder: host::cache_dir() + "/targets".
std::string default_target_cache_dir();

// The key described above (16 hex digits). Reads the VGG weights file named by vgg.path().
std::string target_cache_key(const scene::Scene& scene, const nn::VggEncoder& vgg, host::DType dtype = kTargetDType);

// <dir>/<key>.safetensors.
std::string target_cache_path(const std::string& dir, const std::string& key);

// The targets of every training view, on the device: from the cache when a valid file exists, else
// computed with `vgg` (loaded) and written to the cache.
FeatureTargets load_or_compute_targets(const scene::Scene& scene, nn::VggEncoder& vgg,
                                       const TargetCacheOptions& opts = {});

}  // namespace stylerf::features
