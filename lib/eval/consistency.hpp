// The consistency metric of StyleRF's Table 1 (the authors never released it; this follows the protocol
// of later papers, with exact geometry in place of optical flow): over the first N frames of a camera
// path, frame t is warped into frame t - k by frame t's rendered depth and both cameras (warp.hpp), for
// k = 1 (short range) and k = 7 (long range), and the two are compared on the valid pixels:
//  - masked RMSE: RGB in [0, 1], over valid pixels and channels;
//  - masked LPIPS: frame t against frame t - k sampled at the correspondences, with invalid pixels of the
//    warped image filled from frame t (no difference where nothing is compared), and each LPIPS layer's
//    distance map averaged with the validity mask area-pooled to that layer (lib/eval/lpips.hpp), so only
//    valid pixels count; with every pixel valid it is plain LPIPS.
// A range's score is the mean over its pairs of each pair's score (not pooled over the pairs' pixels: every
// pair weighs the same, however many pixels it has); pairs without a valid pixel are left out of the mean
// and counted (RangeScore::skipped), with NaN scores of their own. The range's valid fraction is the mean
// over all its pairs, the empty ones included.
// The warps depend only on the geometry: computed once per path, they score every method's frames.
#pragma once
#include <functional>
#include <nlohmann/json.hpp>
#include <vector>

#include "lib/eval/warp.hpp"
#include "lib/io/image.hpp"

namespace stylerf::eval {

struct ConsistencyOptions {
  int short_range = 1, long_range = 7;
  WarpOptions warp;
};

// Masked LPIPS (or any masked image distance): a, b same size, mask [H*W] weights.
using MaskedDistance = std::function<double(const io::Image& a, const io::Image& b, const std::vector<float>& mask)>;

// For each range k, the correspondences of frame t into frame t - k, t = k .. n - 1.
struct PathWarps {
  struct Range {
    int k = 0;
    std::vector<Correspondence> warps;  // warps[i]: frame k + i into frame i
  };
  Range short_range, long_range;
  int frames = 0;
};
PathWarps path_warps(const std::vector<FrameGeometry>& frames, const RaySpace& space, const ConsistencyOptions& opt);

struct PairScore {
  int t = 0, s = 0;              // frame t warped into frame s = t - k
  double rmse = 0, lpips = 0;    // NaN when nothing is valid (lpips: also when not measured)
  double valid_fraction = 0;
  WarpStats stats;               // why the other pixels were left out
};
struct RangeScore {
  int k = 0;
  std::vector<PairScore> pairs;
  double rmse = 0, lpips = 0;  // means over the pairs with valid pixels (lpips NaN when not measured)
  int skipped = 0;             // pairs without a valid pixel
  double valid_fraction = 0;   // mean over pairs
};
struct ConsistencyScore {
  RangeScore short_range, long_range;
  nlohmann::json to_json() const;
  // to_json's inverse, exact (how ranks send their scores to rank 0).
  static ConsistencyScore from_json(const nlohmann::json& j);
};

// frames: the method's images of the path, one per warp frame, same sizes. lpips may be null (RMSE only).
// A NaN or infinite pixel in any frame is an Error naming the frame and pixel, never a NaN score.
ConsistencyScore score_frames(const std::vector<io::Image>& frames, const PathWarps& warps,
                              const MaskedDistance* lpips);

}  // namespace stylerf::eval
