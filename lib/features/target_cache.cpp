#include "lib/features/target_cache.hpp"

#include <filesystem>
#include <memory>
#include <ostream>

#include "host/error.hpp"
#include "host/runtime.hpp"
#include "lib/features/content_hash.hpp"
#include "host/files.hpp"
#include "lib/features/target_file.hpp"

namespace stylerf::features {

using host::Error;

namespace {

// Bump when feature_targets.cpp changes what it computes or how it stores it: old cache files then stop
// matching (v2: half precision, streamed file).
constexpr const char* kConvention =
    "relu3_1 v2: reflect pad bottom/right to x8, map pixel i covers pixels 4i..4i+3, crop to ceil(n/4); stored as ";

std::string root_of(const scene::Scene& s) {
  if (s.root.empty()) return "";
  std::error_code ec;
  const auto abs = std::filesystem::weakly_canonical(s.root, ec);
  return ec ? s.root : abs.string();
}

}  // namespace

std::string default_target_cache_dir() { return host::cache_dir() + "/targets"; }

std::string target_cache_key(const scene::Scene& scene, const nn::VggEncoder& vgg, host::DType dtype) {
  if (!vgg.loaded() || vgg.path().empty())
    throw Error("feature targets: the VGG encoder has no weights loaded (nothing to key the cache on)");
  ContentHash h;
  h.text(std::string(kConvention) + host::dtype_name(dtype)).text(root_of(scene)).text(scene.name).text("train");
  h.number(int64_t(scene.train.size())).number(scene.width()).number(scene.height());
  for (const scene::View& v : scene.train) h.text(v.image_path).floats(v.rgb);
  h.text("weights").file(vgg.path());
  return h.hex();
}

std::string target_cache_path(const std::string& dir, const std::string& key) { return dir + "/" + key + ".safetensors"; }

FeatureTargets load_or_compute_targets(const scene::Scene& scene, nn::VggEncoder& vgg, const TargetCacheOptions& opts) {
  if (scene.train.empty()) throw Error("feature targets: scene " + scene.name + " has no training views");
  const std::string key = target_cache_key(scene, vgg, opts.dtype);
  const std::string path =
      opts.use_cache ? target_cache_path(opts.dir.empty() ? default_target_cache_dir() : opts.dir, key) : "";
  std::error_code ec;
  if (opts.use_cache && std::filesystem::exists(path, ec)) {
    FeatureTargets t = allocate_targets(int(scene.train.size()), scene.width(), scene.height(), opts.dtype);
    std::string why;
    try {
      const nlohmann::json meta = read_target_file(path, t);
      if (meta.value("key", std::string()) == key) {
        t.key = key;
        t.from_cache = true;
        if (opts.log) *opts.log << "feature targets: " << t.views() << " views read from " << path << std::endl;
        return t;
      }
      why = "it holds key '" + meta.value("key", std::string()) + "', expected '" + key + "'";
    } catch (const std::exception& e) {  // host::Error from the reader, or json type errors in the metadata
      why = e.what();
    }
    if (opts.log)
      *opts.log << "feature targets: cache file " << path << " not used (" << why << "); recomputing" << std::endl;
  }
  if (opts.log)
    *opts.log << "feature targets: VGG relu3_1 of " << scene.train.size() << " training views at " << scene.width()
              << "x" << scene.height() << " -> " << target_map_size(scene.width()) << "x"
              << target_map_size(scene.height()) << "x" << kTargetChannels << ", stored as "
              << host::dtype_name(opts.dtype) << std::endl;
  if (!opts.use_cache) {
    FeatureTargets t = compute_scene_targets(scene, vgg, opts.dtype, opts.log);
    t.key = key;
    return t;
  }
  FeatureTargets t;
  const nlohmann::json meta = {{"key", key},          {"scene", scene.name},  {"root", root_of(scene)},
                               {"split", "train"},    {"image_width", scene.width()},
                               {"image_height", scene.height()}, {"layer", "relu3_1"},
                               {"convention", std::string(kConvention) + host::dtype_name(opts.dtype)},
                               {"weights", vgg.path()}};
  try {
    const host::Shape shape = target_shape(int(scene.train.size()), scene.width(), scene.height());
    host::write_atomic_with(path, [&](const std::string& tmp) {
      // A file that cannot be written (read-only or full cache) must not stop the computation: its error
      // is kept and thrown once the maps are complete.
      std::unique_ptr<TargetFileWriter> file;
      std::string file_error;
      t = compute_scene_targets(scene, vgg, opts.dtype, opts.log, [&](const std::vector<uint8_t>& bytes) {
        if (!file_error.empty()) return;
        try {
          if (!file) file = std::make_unique<TargetFileWriter>(tmp, opts.dtype, shape, meta);
          file->append(bytes);
        } catch (const Error& e) {
          file_error = e.what();
        }
      });
      if (!file_error.empty()) throw Error(file_error);
      file->finish();
    });
    if (opts.log) *opts.log << "feature targets: cached in " << path << std::endl;
  } catch (const Error& e) {
    // Targets computed in full are valid; a read-only or full cache only costs the next run a recompute.
    if (!t.maps.defined()) throw;
    if (opts.log) *opts.log << "feature targets: could not write the cache (" << e.what() << ")" << std::endl;
  }
  t.key = key;
  return t;
}

}  // namespace stylerf::features
