#include "lib/style/style_encoder.hpp"

#include <cmath>
#include <filesystem>

#include "host/error.hpp"
#include "host/runtime.hpp"
#include "lib/features/content_hash.hpp"
#include "lib/io/safetensors.hpp"
#include "lib/nn/layout.hpp"
#include "lib/style/style_image.hpp"

namespace stylerf::style {

using host::Error;
using host::Tensor;

namespace {
constexpr const char* kConvention = "stylerf style code v1 (256x256 resize, relu3_1, unbiased std)";

bool all_finite(const std::vector<float>& v) {
  for (float x : v)
    if (!std::isfinite(x)) return false;
  return true;
}
}  // namespace

StyleEncoder::StyleEncoder(const Dst& dst, nn::VggEncoder& vgg, std::string cache_dir)
    : dst_(dst), vgg_(vgg), cache_dir_(std::move(cache_dir)) {
  if (!vgg_.loaded()) throw Error("style encoder: the VGG encoder has no weights loaded");
  // The style branch's weights and the VGG file's identity (path, size, time) key the cache: a retrained
  // model or other weights never read a stale code.
  features::ContentHash h;
  h.text(kConvention);
  for (const nn::Param* p : {&dst_.w0, &dst_.b0, &dst_.w2, &dst_.b2, &dst_.w4, &dst_.b4, &dst_.fc_w, &dst_.fc_b})
    h.text(p->name).floats(p->value.to_host());
  std::error_code ec;
  const auto size = std::filesystem::file_size(vgg_.path(), ec);
  const auto time = std::filesystem::last_write_time(vgg_.path(), ec).time_since_epoch().count();
  h.text(vgg_.path()).number(int64_t(ec ? 0 : size)).number(int64_t(ec ? 0 : time));
  model_fingerprint_ = h.hex();
}

std::string StyleEncoder::default_cache_dir() { return host::cache_dir() + "/style_codes"; }

StyleCode StyleEncoder::encode_image(const Tensor& image) const {
  const nn::VggFeatures taps = vgg_.forward(image, 3, false);
  StyleCode code = dst_.style_code(nn::image_to_rows(taps[2]), nullptr);
  if (!all_finite(code.T.to_host()) || !all_finite(code.mean.to_host()) || !all_finite(code.std.to_host()))
    throw Error("style encoder: the style code is not finite (are the model's weights damaged?)");
  return code;
}

StyleEncoder::Encoded StyleEncoder::encode(const std::string& image_path) {
  Encoded out;
  features::ContentHash h;
  h.text(model_fingerprint_).file(image_path);
  out.key = h.hex();
  if (auto it = memory_.find(out.key); it != memory_.end()) {
    out.code = it->second;
    out.from_cache = true;
    return out;
  }
  const std::string file = cache_dir_.empty() ? "" : cache_dir_ + "/" + out.key + ".safetensors";
  std::error_code ec;
  if (!file.empty() && std::filesystem::exists(file, ec)) {
    try {
      const io::SafeTensors st = io::SafeTensors::load(file);
      const auto& mean = st.get("mean", {Dst::kChannels});
      const auto& std = st.get("std", {Dst::kChannels});
      const auto& T = st.get("T", {Dst::kEmbed, Dst::kEmbed});
      if (all_finite(mean.data) && all_finite(std.data) && all_finite(T.data)) {
        out.code.mean = Tensor::from_host(mean.data, {Dst::kChannels}, "style mean");
        out.code.std = Tensor::from_host(std.data, {Dst::kChannels}, "style std");
        out.code.T = Tensor::from_host(T.data, {Dst::kEmbed, Dst::kEmbed}, "style T");
        out.from_cache = true;
      }
    } catch (const Error&) {
      // A damaged or foreign entry: recompute and overwrite it below.
    }
  }
  if (!out.from_cache) {
    out.code = encode_image(load_style_image(image_path, kStyleImageSize, kStyleImageSize, nullptr));
    if (!file.empty()) {
      std::filesystem::create_directories(cache_dir_, ec);
      if (ec) throw Error("style encoder: cannot create the cache folder " + cache_dir_ + ": " + ec.message());
      io::save_safetensors(file,
                       {{"mean", {{Dst::kChannels}, out.code.mean.to_host()}},
                        {"std", {{Dst::kChannels}, out.code.std.to_host()}},
                        {"T", {{Dst::kEmbed, Dst::kEmbed}, out.code.T.to_host()}}},
                       {{"image", image_path}, {"convention", kConvention}});
    }
  }
  memory_[out.key] = out.code;
  return out;
}

void check_mix_weights(const std::vector<float>& weights, size_t count, const std::string& what) {
  if (weights.size() != count)
    throw Error(what + ": " + std::to_string(weights.size()) + " weights for " + std::to_string(count) + " styles");
  double total = 0;
  for (float w : weights) {
    if (!std::isfinite(w) || w < 0) throw Error(what + ": weights must be finite and >= 0");
    total += w;
  }
  if (std::abs(total - 1.0) > 1e-4) throw Error(what + ": weights must sum to 1 (they sum to " + std::to_string(total) + ")");
}

StyleCode mix_codes(const std::vector<StyleCode>& codes, const std::vector<float>& weights, const std::string& what) {
  if (codes.empty()) throw Error(what + ": no styles to mix");
  check_mix_weights(weights, codes.size(), what);
  auto blend = [&](auto field, const char* name) {
    std::vector<float> acc;
    host::Shape shape;
    for (size_t k = 0; k < codes.size(); ++k) {
      const Tensor& t = codes[k].*field;
      const auto v = t.to_host();
      if (acc.empty()) acc.assign(v.size(), 0.0f), shape = t.shape();
      if (v.size() != acc.size()) throw Error(what + ": style codes of different sizes");
      for (size_t i = 0; i < v.size(); ++i) acc[i] += weights[k] * v[i];
    }
    return Tensor::from_host(acc, shape, name);
  };
  StyleCode m;
  m.mean = blend(&StyleCode::mean, "mixed style mean");
  m.std = blend(&StyleCode::std, "mixed style std");
  m.T = blend(&StyleCode::T, "mixed style T");
  return m;
}

}  // namespace stylerf::style
