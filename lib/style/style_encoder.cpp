#include "lib/style/style_encoder.hpp"

#include <cmath>
#include <filesystem>

#include "host/error.hpp"
#include "host/runtime.hpp"
#include "lib/features/content_hash.hpp"
#include "lib/io/safetensors.hpp"
#include "lib/nn/layout.hpp"
#include "lib/nn/ops.hpp"
#include "lib/style/style_image.hpp"

namespace stylerf::style {

using host::Error;
using host::Tensor;

namespace {
constexpr const char* kConvention = "stylerf style code v2 (256x256 resize, relu3_1, unbiased std; relu4_1 stats)";
constexpr int kDeepChannels = 512;  // relu4_1

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
  const nn::VggFeatures taps = vgg_.forward(image, 4, false);
  StyleCode code = dst_.style_code(nn::image_to_rows(taps[2]), nullptr);
  set_relu4_stats(code, taps[3]);
  if (!all_finite(code.T.to_host()) || !all_finite(code.mean.to_host()) || !all_finite(code.std.to_host()) ||
      !all_finite(code.deep_mean.to_host()) || !all_finite(code.deep_std.to_host()))
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
      const auto& deep_mean = st.get("deep_mean", {1, kDeepChannels});
      const auto& deep_std = st.get("deep_std", {1, kDeepChannels});
      if (all_finite(mean.data) && all_finite(std.data) && all_finite(T.data) && all_finite(deep_mean.data) &&
          all_finite(deep_std.data)) {
        out.code.mean = Tensor::from_host(mean.data, {Dst::kChannels}, "style mean");
        out.code.std = Tensor::from_host(std.data, {Dst::kChannels}, "style std");
        out.code.T = Tensor::from_host(T.data, {Dst::kEmbed, Dst::kEmbed}, "style T");
        out.code.deep_mean = Tensor::from_host(deep_mean.data, {1, kDeepChannels}, "style relu4_1 mean");
        out.code.deep_std = Tensor::from_host(deep_std.data, {1, kDeepChannels}, "style relu4_1 std");
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
                        {"T", {{Dst::kEmbed, Dst::kEmbed}, out.code.T.to_host()}},
                        {"deep_mean", {{1, kDeepChannels}, out.code.deep_mean.to_host()}},
                        {"deep_std", {{1, kDeepChannels}, out.code.deep_std.to_host()}}},
                       {{"image", image_path}, {"convention", kConvention}});
    }
  }
  memory_[out.key] = out.code;
  return out;
}

void set_relu4_stats(StyleCode& code, const Tensor& relu4_1) {
  host::expect_shape(relu4_1, {1, kDeepChannels, relu4_1.dim(2), relu4_1.dim(3)}, "style code", "relu4_1 features");
  const nn::ChannelStats s = nn::channel_stats_forward(relu4_1);
  code.deep_mean = s.mean;
  code.deep_std = s.std;
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
  bool deep = true;
  for (const StyleCode& c : codes) deep = deep && c.deep_mean.defined() && c.deep_std.defined();
  if (deep) {  // a convex combination of statistics, as for relu3_1's
    m.deep_mean = blend(&StyleCode::deep_mean, "mixed style relu4_1 mean");
    m.deep_std = blend(&StyleCode::deep_std, "mixed style relu4_1 std");
  }
  return m;
}

}  // namespace stylerf::style
