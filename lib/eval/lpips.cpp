#include "lib/eval/lpips.hpp"

#include <cmath>
#include <string>

#include "host/error.hpp"
#include "lib/eval/lpips_map.hpp"
#include "lib/nn/ops.hpp"
#include "lib/nn/weights.hpp"

namespace stylerf::eval {

using host::Error;
using host::Tensor;

namespace {

// VGG-16's 13 convs: conv i maps kChannels[i] -> kChannels[i + 1] channels. The taps are the relus of
// convs 1, 3, 6, 9, 12 (relu1_2 ... relu5_3), and a 2x2 max pool follows each tap but the last.
constexpr int kConvCount = 13;
constexpr int kChannels[kConvCount + 1] = {3, 64, 64, 128, 128, 256, 256, 256, 512, 512, 512, 512, 512, 512};
constexpr int kTapConv[Lpips::kTaps] = {1, 3, 6, 9, 12};

// lpips' ScalingLayer, applied after x -> 2x - 1.
constexpr float kShift[3] = {-0.030f, -0.088f, -0.188f};
constexpr float kScale[3] = {0.458f, 0.448f, 0.450f};

std::string size_str(const io::Image& im) { return std::to_string(im.width) + "x" + std::to_string(im.height); }

void check_images(const io::Image& a, const io::Image& b) {
  if (a.width != b.width || a.height != b.height)
    throw Error("LPIPS: the images must have the same size, got " + size_str(a) + " and " + size_str(b));
  if (a.width < kLpipsMinSide || a.height < kLpipsMinSide)
    throw Error("LPIPS: images must be at least " + std::to_string(kLpipsMinSide) + "x" +
                std::to_string(kLpipsMinSide) + " (four 2x2 poolings before relu5_3), got " + size_str(a));
  const size_t n = size_t(3) * a.width * a.height;
  if (a.data.size() != n || b.data.size() != n)
    throw Error("LPIPS: image data does not match its size " + size_str(a) + " (expected 3 planes)");
}

// The mask at the next tap: 2x2 block means, floored like the pooling.
std::vector<double> pool_mask(const std::vector<double>& m, int h, int w) {
  const int ho = h / 2, wo = w / 2;
  std::vector<double> out(size_t(ho) * wo);
  for (int y = 0; y < ho; ++y)
    for (int x = 0; x < wo; ++x) {
      const size_t i = size_t(2 * y) * w + 2 * x;
      out[size_t(y) * wo + x] = 0.25 * (m[i] + m[i + 1] + m[i + w] + m[i + w + 1]);
    }
  return out;
}

}  // namespace

void Lpips::load(const std::string& path) {
  io::SafeTensors st = nn::load_weights(path);
  if (st.has("trunk.0.weight") && st.get("trunk.0.weight").shape == std::vector<int64_t>{64, 3, 11, 11})
    throw Error(path + ": AlexNet LPIPS weights; only the VGG-16 variant is built (use " + kLpipsVggWeightsFile + ")");
  if (!st.has("trunk.0.weight") || !st.has("lin.0.weight"))
    throw Error(path + ": not LPIPS weights: expected trunk.<i>.weight/bias and lin.<l>.weight (written by "
                       "scripts/fetch_lpips.py; run `" + std::string(nn::kFetchWeightsCommand) + "`)");
  std::vector<Conv> convs;
  {  // 2x - 1, then (x - shift) / scale, as one fixed diagonal 1x1 conv
    std::vector<float> w(9, 0.0f), b(3);
    for (int c = 0; c < 3; ++c) {
      w[c * 3 + c] = 2.0f / kScale[c];
      b[c] = (-1.0f - kShift[c]) / kScale[c];
    }
    convs.push_back({Tensor::from_host(w, {3, 3, 1, 1}, "lpips input.w"), Tensor::from_host(b, {3}, "lpips input.b")});
  }
  for (int i = 0; i < kConvCount; ++i) {
    const std::string key = "trunk." + std::to_string(i);
    const auto& w = st.get(key + ".weight", {kChannels[i + 1], kChannels[i], 3, 3});
    const auto& b = st.get(key + ".bias", {kChannels[i + 1]});
    convs.push_back({Tensor::from_host(w.data, w.shape, "lpips " + key + ".w"),
                     Tensor::from_host(b.data, b.shape, "lpips " + key + ".b")});
  }
  std::vector<Tensor> lin;
  for (int l = 0; l < kTaps; ++l) {
    const std::string key = "lin." + std::to_string(l) + ".weight";
    lin.push_back(Tensor::from_host(st.get(key, {kChannels[kTapConv[l] + 1]}).data, {kChannels[kTapConv[l] + 1]},
                                    "lpips " + key));
  }
  convs_ = std::move(convs);
  lin_ = std::move(lin);
  path_ = path;
}

Lpips Lpips::load_default() {
  Lpips l;
  l.load(nn::weights_path(kLpipsVggWeightsFile));
  return l;
}

std::vector<std::array<int, 2>> Lpips::tap_sizes(int height, int width) {
  std::vector<std::array<int, 2>> s;
  for (int l = 0; l < kTaps; ++l, height /= 2, width /= 2) s.push_back({height, width});
  return s;
}

std::vector<Tensor> Lpips::distance_maps(const Tensor& a, const Tensor& b) const {
  if (!loaded()) throw Error("Lpips::distance_maps: no weights loaded");
  if (a.ndim() != 4 || a.dim(0) != 1 || a.dim(1) != 3)
    throw Error("Lpips::distance_maps: images must be [1,3,H,W], got " + host::shape_str(a.shape()));
  host::expect_shape(b, a.shape(), "Lpips::distance_maps", "b");
  if (a.dim(2) < kLpipsMinSide || a.dim(3) < kLpipsMinSide)
    throw Error("Lpips::distance_maps: H and W must be >= " + std::to_string(kLpipsMinSide) + ", got " +
                host::shape_str(a.shape()));
  // Both images step through the trunk together, so only the current activations of each are alive.
  Tensor ha = nn::conv2d_forward(a, convs_[0].w, convs_[0].b, nn::Padding::Zero);
  Tensor hb = nn::conv2d_forward(b, convs_[0].w, convs_[0].b, nn::Padding::Zero);
  std::vector<Tensor> maps;
  for (int i = 0; i < kConvCount; ++i) {
    const Conv& c = convs_[i + 1];
    ha = nn::relu_forward(nn::conv2d_forward(ha, c.w, c.b, nn::Padding::Zero));
    hb = nn::relu_forward(nn::conv2d_forward(hb, c.w, c.b, nn::Padding::Zero));
    const int tap = int(maps.size());
    if (i != kTapConv[tap]) continue;
    maps.push_back(lpips_distance_map(ha, hb, lin_[tap]));
    if (tap + 1 < kTaps) {
      ha = nn::maxpool2x2_forward(ha);
      hb = nn::maxpool2x2_forward(hb);
    }
  }
  return maps;
}

double Lpips::pooled(const io::Image& a, const io::Image& b, const std::vector<float>* mask) const {
  check_images(a, b);
  const int h = a.height, w = a.width;
  std::vector<double> m;  // the mask at the current tap; empty: unmasked (every weight 1)
  if (mask) {
    if (mask->size() != size_t(h) * w)
      throw Error("LPIPS: the mask has " + std::to_string(mask->size()) + " values, the images " + size_str(a) +
                  " need " + std::to_string(size_t(h) * w));
    m.resize(mask->size());
    for (size_t i = 0; i < m.size(); ++i) {
      const float v = (*mask)[i];
      if (!(v >= 0.0f && v <= 1.0f))
        throw Error("LPIPS: mask value " + std::to_string(v) + " at pixel " + std::to_string(i % w) + "," +
                    std::to_string(i / w) + " is outside [0, 1]");
      m[i] = v;
    }
  }
  const std::vector<Tensor> maps = distance_maps(io::to_tensor(a), io::to_tensor(b));
  const auto sizes = tap_sizes(h, w);
  double total = 0.0;
  for (int l = 0; l < kTaps; ++l) {
    if (l > 0 && mask) m = pool_mask(m, sizes[l - 1][0], sizes[l - 1][1]);
    const std::vector<float> d = maps[l].to_host();
    double num = 0.0, den = 0.0;
    for (size_t p = 0; p < d.size(); ++p) {
      const double wp = mask ? m[p] : 1.0;
      num += wp * d[p];
      den += wp;
    }
    if (den > 0.0) total += num / den;  // a tap with no mask weight contributes 0
  }
  return total;
}

double Lpips::distance(const io::Image& a, const io::Image& b) const { return pooled(a, b, nullptr); }

double Lpips::distance(const io::Image& a, const io::Image& b, const std::vector<float>& mask) const {
  return pooled(a, b, &mask);
}

}  // namespace stylerf::eval
