#include "lib/features/target_cache.hpp"

#include <filesystem>
#include <ostream>

#include "host/error.hpp"
#include "host/runtime.hpp"
#include "lib/features/content_hash.hpp"
#include "lib/io/checkpoint.hpp"

namespace stylerf::features {

using host::Error;

namespace {

constexpr const char* kKind = "feature-targets";
constexpr const char* kTensor = "targets";
// Bump when feature_targets.cpp changes what it computes: old cache files then stop matching.
constexpr const char* kConvention =
    "relu3_1 v1: reflect pad bottom/right to x8, map pixel i covers pixels 4i..4i+3, crop to ceil(n/4)";

std::string root_of(const scene::Scene& s) {
  if (s.root.empty()) return "";
  std::error_code ec;
  const auto abs = std::filesystem::weakly_canonical(s.root, ec);
  return ec ? s.root : abs.string();
}

// Why the cache file cannot stand in for the targets of `key`, or "" when it can.
std::string mismatch(const io::Checkpoint& ck, const std::string& key, const host::Shape& shape) {
  const std::string stored = ck.meta.value("key", std::string());
  if (stored != key) return "it holds key '" + stored + "', expected '" + key + "'";
  auto it = ck.tensors.find(kTensor);
  if (it == ck.tensors.end()) return std::string("it has no tensor '") + kTensor + "'";
  if (it->second.shape != shape)
    return "its targets have shape " + host::shape_str(it->second.shape) + ", expected " + host::shape_str(shape);
  if (ck.meta.value("shape", std::vector<int64_t>{}) != shape) return "its metadata names another shape";
  return "";
}

}  // namespace

std::string default_target_cache_dir() { return host::cache_dir() + "/targets"; }

std::string target_cache_key(const scene::Scene& scene, const nn::VggEncoder& vgg) {
  if (!vgg.loaded() || vgg.path().empty())
    throw Error("feature targets: the VGG encoder has no weights loaded (nothing to key the cache on)");
  ContentHash h;
  h.text(kConvention).text(root_of(scene)).text(scene.name).text("train");
  h.number(int64_t(scene.train.size())).number(scene.width()).number(scene.height());
  for (const scene::View& v : scene.train) h.text(v.image_path).floats(v.rgb);
  h.text("weights").file(vgg.path());
  return h.hex();
}

std::string target_cache_path(const std::string& dir, const std::string& key) { return dir + "/" + key + ".safetensors"; }

FeatureTargets load_or_compute_targets(const scene::Scene& scene, nn::VggEncoder& vgg, const TargetCacheOptions& opts) {
  if (scene.train.empty()) throw Error("feature targets: scene " + scene.name + " has no training views");
  FeatureTargets t;
  t.image_width = scene.width();
  t.image_height = scene.height();
  t.key = target_cache_key(scene, vgg);
  const host::Shape shape{int64_t(scene.train.size()), target_map_size(t.image_height),
                          target_map_size(t.image_width), kTargetChannels};
  std::string path;
  if (opts.use_cache) {
    path = target_cache_path(opts.dir.empty() ? default_target_cache_dir() : opts.dir, t.key);
    std::error_code ec;
    if (std::filesystem::exists(path, ec)) {
      std::string why;
      try {
        io::Checkpoint ck = io::load_checkpoint(path, kKind);
        why = mismatch(ck, t.key, shape);
        if (why.empty()) {
          t.maps = host::Tensor::from_host(ck.tensors[kTensor].data, shape, "feature targets");
          t.from_cache = true;
          if (opts.log) *opts.log << "feature targets: " << shape[0] << " views read from " << path << std::endl;
          return t;
        }
      } catch (const std::exception& e) {  // host::Error from the reader, or json type errors in the metadata
        why = e.what();
      }
      if (opts.log)
        *opts.log << "feature targets: cache file " << path << " not used (" << why << "); recomputing" << std::endl;
    }
  }
  if (opts.log)
    *opts.log << "feature targets: VGG relu3_1 of " << shape[0] << " training views at " << t.image_width << "x"
              << t.image_height << " -> " << shape[2] << "x" << shape[1] << "x" << kTargetChannels << std::endl;
  io::Checkpoint ck;
  ck.kind = kKind;
  io::HostTensor& data = ck.tensors[kTensor];
  data.shape = shape;
  data.data = compute_scene_targets(scene, vgg, opts.log);
  if (opts.use_cache) {
    ck.meta = {{"key", t.key},           {"shape", shape},         {"scene", scene.name},
               {"root", root_of(scene)}, {"split", "train"},       {"image_width", t.image_width},
               {"image_height", t.image_height}, {"layer", "relu3_1"}, {"convention", kConvention},
               {"weights", vgg.path()}};
    try {
      io::save_checkpoint(path, ck);
      if (opts.log) *opts.log << "feature targets: cached in " << path << std::endl;
    } catch (const Error& e) {
      // The targets in memory are valid; a read-only or full cache only costs the next run a recompute.
      if (opts.log) *opts.log << "feature targets: could not write the cache (" << e.what() << ")" << std::endl;
    }
  }
  t.maps = host::Tensor::from_host(data.data, shape, "feature targets");
  return t;
}

}  // namespace stylerf::features
