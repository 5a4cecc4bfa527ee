#include "lib/eval/lpips.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "host/error.hpp"
#include "lib/eval/finite_image.hpp"
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

// AlexNet's 5 convs (cout, cin, k, stride, zero pad); every relu is a tap, and a 3x3 stride-2 max pool
// follows taps 0 and 1.
struct AlexConv {
  int cout, cin, k, stride, pad;
};
constexpr AlexConv kAlex[Lpips::kTaps] = {
    {64, 3, 11, 4, 2}, {192, 64, 5, 1, 2}, {384, 192, 3, 1, 1}, {256, 384, 3, 1, 1}, {256, 256, 3, 1, 1}};
constexpr int kAlexPool = 3, kAlexPoolStride = 2, kAlexPooledTaps = 2;

// lpips' ScalingLayer, applied after x -> 2x - 1.
constexpr float kShift[3] = {-0.030f, -0.088f, -0.188f};
constexpr float kScale[3] = {0.458f, 0.448f, 0.450f};

std::string size_str(const io::Image& im) { return std::to_string(im.width) + "x" + std::to_string(im.height); }

// Why the net needs its minimum size, for error messages.
std::string min_side_reason(LpipsNet net) {
  const int m = lpips_min_side(net);
  const std::string mm = std::to_string(m) + "x" + std::to_string(m);
  return net == LpipsNet::Vgg ? "at least " + mm + " (four 2x2 poolings before relu5_3)"
                              : "at least " + mm + " for AlexNet (conv1 11x11 stride 4, then two 3x3 stride-2 "
                                                   "poolings must leave 1x1 for relu3..relu5)";
}

void check_images(LpipsNet net, const io::Image& a, const io::Image& b) {
  if (a.width != b.width || a.height != b.height)
    throw Error("LPIPS: the images must have the same size, got " + size_str(a) + " and " + size_str(b));
  if (a.width < lpips_min_side(net) || a.height < lpips_min_side(net))
    throw Error("LPIPS: images must be " + min_side_reason(net) + ", got " + size_str(a));
  const size_t n = size_t(3) * a.width * a.height;
  if (a.data.size() != n || b.data.size() != n)
    throw Error("LPIPS: image data does not match its size " + size_str(a) + " (expected 3 planes)");
  for (const io::Image* im : {&a, &b})
    if (const std::string bad = non_finite_at(*im); !bad.empty())
      throw Error(std::string("LPIPS: image ") + (im == &a ? "a" : "b") + " has " + bad);
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

// Area average of an H x W map onto h x w cells (h <= H, w <= W): cell (y, x) is the mean of M over
// [y H / h, (y + 1) H / h) x [x W / w, (x + 1) W / w), a pixel partly inside weighted by the part covered
// (io::resize's shrinking rule, in double). Separable: rows first, then columns.
std::vector<double> area_mean(const std::vector<double>& m, int H, int W, int h, int w) {
  struct Tap {
    int i;
    double weight;
  };
  auto axis = [](int src, int dst) {
    std::vector<std::vector<Tap>> taps(dst);
    const double scale = double(src) / dst;
    for (int o = 0; o < dst; ++o) {
      const double lo = o * scale, hi = (o + 1) * scale;
      for (int i = int(std::floor(lo)); i < src && i < hi; ++i) {
        const double cover = std::min(hi, i + 1.0) - std::max(lo, double(i));
        if (cover > 0) taps[o].push_back({i, cover / scale});
      }
    }
    return taps;
  };
  const auto ty = axis(H, h), tx = axis(W, w);
  std::vector<double> rows(size_t(h) * W, 0.0), out(size_t(h) * w, 0.0);
  for (int y = 0; y < h; ++y)
    for (const Tap& t : ty[y])
      for (int x = 0; x < W; ++x) rows[size_t(y) * W + x] += t.weight * m[size_t(t.i) * W + x];
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (const Tap& t : tx[x]) out[size_t(y) * w + x] += t.weight * rows[size_t(y) * W + t.i];
  return out;
}

}  // namespace

const char* lpips_net_name(LpipsNet net) { return net == LpipsNet::Vgg ? "vgg" : "alex"; }

LpipsNet parse_lpips_net(const std::string& name) {
  if (name == "vgg") return LpipsNet::Vgg;
  if (name == "alex") return LpipsNet::Alex;
  throw Error("LPIPS: unknown net '" + name + "' (vgg: VGG-16, alex: AlexNet)");
}

const char* lpips_weights_file(LpipsNet net) {
  return net == LpipsNet::Vgg ? kLpipsVggWeightsFile : kLpipsAlexWeightsFile;
}

int lpips_min_side(LpipsNet net) { return net == LpipsNet::Vgg ? kLpipsMinSide : kLpipsAlexMinSide; }

void Lpips::load(const std::string& path) {
  io::SafeTensors st = nn::load_weights(path);
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
    convs.push_back(
        {Tensor::from_host(w, {3, 3, 1, 1}, "lpips input.w"), Tensor::from_host(b, {3}, "lpips input.b"), 1, 0, {}});
  }
  // The trunk, from the first conv's kernel: 11x11 is AlexNet; anything else must be VGG-16's 3x3 (a
  // mis-shaped VGG tensor is then reported by st.get with its expected shape).
  const bool alex = st.get("trunk.0.weight").shape == std::vector<int64_t>{64, 3, 11, 11};
  auto add_conv = [&](int i, int cout, int cin, int k, int stride, int pad) {
    const std::string key = "trunk." + std::to_string(i);
    const auto& w = st.get(key + ".weight", {cout, cin, k, k});
    const auto& b = st.get(key + ".bias", {cout});
    convs.push_back({Tensor::from_host(w.data, w.shape, "lpips " + key + ".w"),
                     Tensor::from_host(b.data, b.shape, "lpips " + key + ".b"), stride, pad, {}});
  };
  std::vector<Tensor> lin;
  auto add_lin = [&](int l, int channels) {
    const std::string key = "lin." + std::to_string(l) + ".weight";
    lin.push_back(Tensor::from_host(st.get(key, {channels}).data, {channels}, "lpips " + key));
  };
  if (alex) {
    for (int i = 0; i < kTaps; ++i)
      add_conv(i, kAlex[i].cout, kAlex[i].cin, kAlex[i].k, kAlex[i].stride, kAlex[i].pad);
    for (int l = 0; l < kTaps; ++l) add_lin(l, kAlex[l].cout);
  } else {
    for (int i = 0; i < kConvCount; ++i) add_conv(i, kChannels[i + 1], kChannels[i], 3, 1, 1);
    for (int l = 0; l < kTaps; ++l) add_lin(l, kChannels[kTapConv[l] + 1]);
  }
  if (st.has("trunk." + std::to_string(alex ? kTaps : kConvCount) + ".weight"))
    throw Error(path + ": more trunk convs than " + (alex ? "AlexNet's 5" : "VGG-16's 13") +
                " (trunk." + std::to_string(alex ? kTaps : kConvCount) + ".weight): not LPIPS v0.1 weights");
  convs_ = std::move(convs);
  lin_ = std::move(lin);
  net_ = alex ? LpipsNet::Alex : LpipsNet::Vgg;
  path_ = path;
}

Lpips Lpips::load_default(LpipsNet net) {
  Lpips l;
  l.load(nn::weights_path(lpips_weights_file(net)));
  if (l.net() != net)  // e.g. a VGG file saved under the AlexNet name
    throw Error(l.path() + ": holds the " + (l.net() == LpipsNet::Vgg ? "VGG-16" : "AlexNet") +
                " LPIPS weights, expected " + (net == LpipsNet::Vgg ? "VGG-16" : "AlexNet") + " (rerun `" +
                nn::kFetchWeightsCommand + " --force`)");
  return l;
}

std::vector<std::array<int, 2>> Lpips::tap_sizes(int height, int width) {
  return tap_sizes(LpipsNet::Vgg, height, width);
}

std::vector<std::array<int, 2>> Lpips::tap_sizes(LpipsNet net, int height, int width) {
  std::vector<std::array<int, 2>> s;
  if (net == LpipsNet::Vgg) {
    for (int l = 0; l < kTaps; ++l, height /= 2, width /= 2) s.push_back({height, width});
    return s;
  }
  auto pool = [](int n) { return n >= kAlexPool ? (n - kAlexPool) / kAlexPoolStride + 1 : 0; };
  int h = std::max(0, nn::conv2d_output_size(height, kAlex[0].k, kAlex[0].stride, kAlex[0].pad));
  int w = std::max(0, nn::conv2d_output_size(width, kAlex[0].k, kAlex[0].stride, kAlex[0].pad));
  for (int l = 0; l < kTaps; ++l) {
    s.push_back({h, w});
    if (l < kAlexPooledTaps) h = pool(h), w = pool(w);
  }
  return s;
}

Tensor Lpips::conv_relu(const Tensor& x, const Conv& c) const {
  const int k = int(c.w.dim(2));
  // The stride-1 "same" 3x3 convs take conv2d's faster path; the others (AlexNet's 11x11/4 and 5x5) the
  // general one.
  const Tensor y = k == 3 && c.stride == 1 && c.pad == 1
                       ? nn::conv2d_forward(x, c.w, c.b, nn::Padding::Zero, nn::ConvAlgo::Auto, &c.filters)
                       : nn::conv2d_strided_forward(x, c.w, c.b, c.stride, c.pad);
  return nn::relu_forward(y);
}

std::vector<Tensor> Lpips::distance_maps(const Tensor& a, const Tensor& b) const {
  if (!loaded()) throw Error("Lpips::distance_maps: no weights loaded");
  if (a.ndim() != 4 || a.dim(0) != 1 || a.dim(1) != 3)
    throw Error("Lpips::distance_maps: images must be [1,3,H,W], got " + host::shape_str(a.shape()));
  host::expect_shape(b, a.shape(), "Lpips::distance_maps", "b");
  if (a.dim(2) < min_side() || a.dim(3) < min_side())
    throw Error("Lpips::distance_maps: H and W must be >= " + std::to_string(min_side()) +
                (net_ == LpipsNet::Alex ? " (AlexNet)" : "") + ", got " + host::shape_str(a.shape()));
  // Both images step through the trunk together, so only the current activations of each are alive.
  Tensor ha = nn::conv2d_forward(a, convs_[0].w, convs_[0].b, nn::Padding::Zero);
  Tensor hb = nn::conv2d_forward(b, convs_[0].w, convs_[0].b, nn::Padding::Zero);
  std::vector<Tensor> maps;
  if (net_ == LpipsNet::Alex) {
    for (int l = 0; l < kTaps; ++l) {
      ha = conv_relu(ha, convs_[l + 1]);
      hb = conv_relu(hb, convs_[l + 1]);
      maps.push_back(lpips_distance_map(ha, hb, lin_[l]));
      if (l < kAlexPooledTaps) {
        ha = nn::maxpool_forward(ha, kAlexPool, kAlexPoolStride);
        hb = nn::maxpool_forward(hb, kAlexPool, kAlexPoolStride);
      }
    }
    return maps;
  }
  for (int i = 0; i < kConvCount; ++i) {
    ha = conv_relu(ha, convs_[i + 1]);
    hb = conv_relu(hb, convs_[i + 1]);
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
  if (!loaded()) throw Error("Lpips::distance: no weights loaded");
  check_images(net_, a, b);
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
  const auto sizes = tap_sizes(net_, h, w);
  const std::vector<double> full = m;
  double total = 0.0;
  for (int l = 0; l < kTaps; ++l) {
    if (mask && net_ == LpipsNet::Vgg && l > 0) m = pool_mask(m, sizes[l - 1][0], sizes[l - 1][1]);
    if (mask && net_ == LpipsNet::Alex) m = area_mean(full, h, w, sizes[l][0], sizes[l][1]);
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
