// Stage-2 feature targets: VGG-19 relu3_1 (256 channels) of every training view, kept at relu3_1's own
// resolution, 1/4 of the image's, and upsampled only where a ray samples them (target_gather.hpp). Full
// resolution maps would take lego at 1/4 (100 views at 200^2) to 4 GB; these take 256 MB in float.
//
// Storage: half precision by default (F16; `stylerf bench targets` measures each choice). Lego at its own
// 800x800 needs 100 x 200^2 x 256 maps: 4.1 GB in float, 2.05 GB in half. relu3_1 values are >= 0 and
// below a few hundred; half keeps 11 significant bits (relative error <= 2^-11, 0.05%), far below the
// distillation's own error. The maps are filled one view at a time, so no host copy of the whole exists.
//
// Geometry (the convention everything in lib/features follows):
//  - The image is reflect-padded at the bottom and right only, to multiples of 8 (VggEncoder needs them),
//    so no pixel moves; relu3_1 comes after two 2x2 max pools, so map pixel (i, j) covers image pixels
//    rows 4i..4i+3, columns 4j..4j+3, and its centre sits at image coordinate (4j + 2, 4i + 2).
//  - The map is cropped to Hf = ceil(H / 4), Wf = ceil(W / 4): every image pixel falls in one map pixel,
//    and map pixels made only of padding are dropped.
//  - A full-resolution position (px, py), with pixel (x, y)'s centre at (x + 0.5, y + 0.5) as in
//    lib/scene, maps to feature coordinates (px / 4 - 0.5, py / 4 - 0.5), sampled bilinearly and clamped at
//    the borders. At pixel centres and W, H multiples of 4 this is exactly the authors'
//    F.interpolate(map, size=(H, W), mode='bilinear', align_corners=False); for other sizes we keep the
//    true 4x pooling geometry rather than stretching the map over the image.
//  - Reflect padding of a dimension n < padded size folds repeatedly (period 2(n-1); n = 1 repeats the
//    pixel), so images smaller than 8 pixels work too.
#pragma once
#include <cstdint>
#include <functional>
#include <iosfwd>
#include <string>
#include <vector>

#include "host/tensor.hpp"
#include "lib/nn/vgg.hpp"
#include "lib/scene/scene.hpp"

namespace stylerf::features {

constexpr int kTargetChannels = 256;  // relu3_1
constexpr int kTargetStride = 4;      // image pixels per map pixel, per axis

// ceil(n / 4): map size along an image axis of n pixels.
int target_map_size(int pixels);

// Index into [0, n) of position i after reflect padding (edge not repeated), folding as often as needed.
int reflect_index(int i, int n);

// rgb [h][w][3] interleaved -> [3][ph][pw] planar with ph, pw the next multiples of `multiple`, padded at
// the bottom and right by reflect_index.
std::vector<float> pad_to_multiple_chw(const std::vector<float>& rgb, int h, int w, int multiple, int& ph, int& pw);

struct FeatureTargets {
  host::Tensor maps;  // [V, Hf, Wf, 256] F16 or F32, channels innermost: one bilinear tap reads 256 contiguous values
  int image_width = 0, image_height = 0;  // the full-resolution size the maps describe
  std::string key;                        // the cache key of the inputs (target_cache.hpp)
  bool from_cache = false;                // read from the disk cache rather than computed

  int views() const { return maps.defined() ? int(maps.dim(0)) : 0; }
  int map_height() const { return maps.defined() ? int(maps.dim(1)) : 0; }
  int map_width() const { return maps.defined() ? int(maps.dim(2)) : 0; }
};

// The storage the training stages use.
constexpr host::DType kTargetDType = host::DType::F16;

// [views, ceil(H/4), ceil(W/4), 256]: the maps' shape for views of image_width x image_height pixels.
host::Shape target_shape(int views, int image_width, int image_height);

// Uninitialised maps for `views` views of image_width x image_height images, stored as `dtype` (F16 or F32).
FeatureTargets allocate_targets(int views, int image_width, int image_height, host::DType dtype = kTargetDType);

// One view's map [Hf][Wf][C] (floats) as the bytes `dtype` stores (F16: IEEE half bits, F32: as is): what
// put_view writes and the target cache file holds.
std::vector<uint8_t> encode_view(const std::vector<float>& hwc, host::DType dtype);
// Writes view `view`'s bytes (encode_view with the maps' dtype) into the maps.
void put_view(FeatureTargets& targets, int view, const std::vector<uint8_t>& bytes);
// Bytes per view of the maps.
size_t view_bytes(const FeatureTargets& targets);
// All maps as floats [V][Hf][Wf][C] on the host, whatever their dtype (tests, tools; a full host copy).
std::vector<float> maps_to_host(const FeatureTargets& targets);

// relu3_1 of one image (rgb [h][w][3] in [0,1]) as a host array [Hf][Wf][256].
std::vector<float> compute_view_targets(nn::VggEncoder& vgg, const std::vector<float>& rgb, int h, int w);

// Every training view of `scene`, in order, stored as `dtype`, one view at a time; `each_view` (if set) gets
// every view's bytes as they are written (the cache file streams them). Prints a progress line (views/s) to
// `log` about every two seconds and a summary at the end. Errors name the view's image when the views differ
// in size or have no pixels loaded.
FeatureTargets compute_scene_targets(const scene::Scene& scene, nn::VggEncoder& vgg, host::DType dtype,
                                     std::ostream* log,
                                     const std::function<void(const std::vector<uint8_t>&)>& each_view = {});

}  // namespace stylerf::features
