// A picture of a C-channel feature map: its three principal components as RGB. One PCA is fitted (to
// the first frame, or any set of maps) and then applied unchanged to every frame, so colours mean the
// same thing across a video. Components by power iteration with deflation on the covariance, in double,
// from a fixed subsample (deterministic); each component's sign is fixed so its largest loading is
// positive; the colour range is the 1st..99th percentile of the fit set's projections.
#pragma once
#include <vector>

namespace stylerf::eval {

struct FeaturePca {
  int channels = 0;
  std::vector<double> mean;        // [C]
  std::vector<double> components;  // [3][C]
  double lo[3] = {0, 0, 0}, hi[3] = {1, 1, 1};

  // features: [N][C] pixel-major rows (N = H*W). Uses at most max_samples rows, evenly spaced.
  static FeaturePca fit(const std::vector<float>& features, int channels, int max_samples = 20000);
  // [N][3] in [0,1], interleaved RGB.
  std::vector<float> apply(const std::vector<float>& features) const;
};

// [1,C,H,W] planar (as a device map reads back) -> [H*W][C] rows.
std::vector<float> planar_to_rows(const std::vector<float>& chw, int channels, int pixels);

}  // namespace stylerf::eval
