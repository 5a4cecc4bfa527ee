// Zero-shot style encoding: a style image -> its StyleCode (relu3_1 mean and std, T; relu4_1's statistics
// for the vgg-adain-relu4 decoder) through VGG and the
// trained DST style branch, with no optimisation. Codes are cached by the image's content hash together
// with a fingerprint of the style branch's weights and the VGG weights file, so a style is encoded once per
// model: in memory for this process and, when a cache folder is given, on disk across runs
// (<dir>/<key>.safetensors, written atomically; a damaged entry is recomputed, not trusted).
//
// Interpolation (StyleRF Fig. 6): a convex combination of codes, mixing T, mean and std with the same
// weights; DST is linear in each, so this interpolates the transformation itself.
#pragma once
#include <map>
#include <string>
#include <vector>

#include "lib/nn/vgg.hpp"
#include "lib/style/dst.hpp"

namespace stylerf::style {

constexpr int kStyleImageSize = 256;  // style images are resized to 256 x 256 (the authors' test transform)

class StyleEncoder {
 public:
  // cache_dir "": memory only. The encoder keeps references: dst and vgg must outlive it.
  StyleEncoder(const Dst& dst, nn::VggEncoder& vgg, std::string cache_dir = "");
  static std::string default_cache_dir();  // <stylerf cache>/style_codes

  struct Encoded {
    StyleCode code;
    std::string key;
    bool from_cache = false;  // memory or disk
  };
  Encoded encode(const std::string& image_path);
  // The code of an image already loaded ([1, 3, h, w], h and w multiples of 8); no caching.
  StyleCode encode_image(const host::Tensor& image) const;

 private:
  const Dst& dst_;
  nn::VggEncoder& vgg_;
  std::string cache_dir_;
  std::string model_fingerprint_;
  std::map<std::string, StyleCode> memory_;
};

// Sets code.deep_mean / deep_std from a style image's relu4_1 features [1, 512, h, w].
void set_relu4_stats(StyleCode& code, const host::Tensor& relu4_1);

// Throws unless there are `count` weights, finite, >= 0, summing to 1 (within 1e-4); the error names `what`.
void check_mix_weights(const std::vector<float>& weights, size_t count, const std::string& what);
// sum_k w_k code_k. The weights must be finite, >= 0 and sum to 1 (within 1e-4); the error names `what`.
StyleCode mix_codes(const std::vector<StyleCode>& codes, const std::vector<float>& weights,
                    const std::string& what = "--mix");

}  // namespace stylerf::style
