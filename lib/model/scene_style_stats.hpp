// Scene-level relu4_1 statistics for the vgg-adain-relu4 style decoder at inference.
//
// That decoder re-normalises VGG's relu4_1 of each decoded map to the style's relu4_1 statistics. With a
// frame's own statistics (what training uses, per patch), every frame gets its own per-channel affine
// map, and the whole frame shifts as the view changes: on the generated 128 px scene short-range RMSE
// was 1.21x per-frame 2D AdaIN's. Fixing the source statistics once per style, pooled over the maps of a
// few training views under that style, gives every frame of the scene the same map, as SICT fixes its
// own statistics once for the scene (docs/results.md: what it measured).
#pragma once
#include <vector>

#include "lib/model/style_model.hpp"

namespace stylerf::model {

// relu4_1 statistics pooled over every pixel of every map (each [1, C, h, w] or [n, C, h, w]): per channel
// the mean, sqrt(biased variance + 1e-5) as nn::channel_stats_forward, and the range, each [1, C].
struct PooledRelu4Stats {
  Tensor mean, std, lo, hi;
};
PooledRelu4Stats pool_relu4_stats(const std::vector<Tensor>& maps);

class SceneStyleStats {
 public:
  static constexpr int kDefaultViews = 6;
  // Renders the style-independent content of `views` training views, evenly spaced (once), at the rays a
  // block the frames it re-normalises are rendered with (`supersample`; 0: the model's
  // inference_supersample): a block's content is the mean of its rays', and a mean of 9 varies less than
  // one ray does, so statistics of one-ray maps would scale 3x3 frames' relu4_1 by a std they do not have.
  SceneStyleStats(const StyleModel& m, const scene::Scene& scene, int views = kDefaultViews, int supersample = 0,
                  float refine_contrast = kRefineContrast);
  // Sets code.scene_mean / scene_std: relu4_1 statistics of the views' maps under the code, pooled over
  // every pixel of every view (biased variance + 1e-5, as nn::channel_stats_forward). No-op for decoders
  // that read no relu4_1 statistics.
  void attach(style::StyleCode& code) const;

 private:
  const StyleModel* m_;
  std::vector<StyleModel::CameraContent> views_;
};

}  // namespace stylerf::model
