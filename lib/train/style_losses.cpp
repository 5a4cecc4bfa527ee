#include "lib/train/style_losses.hpp"

#include <algorithm>
#include <cmath>

#include "host/error.hpp"
#include "host/launch.hpp"
#include "lib/nn/ops.hpp"

namespace stylerf::train {

using host::Error;

namespace {
// PyTorch's F.interpolate(mode="bilinear", align_corners=False) of one channel.
std::vector<float> resize_bilinear(const std::vector<float>& src, int h, int w, int H, int W) {
  std::vector<float> out(size_t(H) * W);
  const float sy = float(h) / float(H), sx = float(w) / float(W);
  for (int y = 0; y < H; ++y) {
    const float fy = std::max(0.0f, (float(y) + 0.5f) * sy - 0.5f);
    const int y0 = std::min(int(fy), h - 1), y1 = std::min(y0 + 1, h - 1);
    const float ty = fy - float(y0);
    for (int x = 0; x < W; ++x) {
      const float fx = std::max(0.0f, (float(x) + 0.5f) * sx - 0.5f);
      const int x0 = std::min(int(fx), w - 1), x1 = std::min(x0 + 1, w - 1);
      const float tx = fx - float(x0);
      const float a = src[size_t(y0) * w + x0] * (1 - tx) + src[size_t(y0) * w + x1] * tx;
      const float b = src[size_t(y1) * w + x0] * (1 - tx) + src[size_t(y1) * w + x1] * tx;
      out[size_t(y) * W + x] = a * (1 - ty) + b * ty;
    }
  }
  return out;
}

double scalar(const Tensor& t) { return double(t.to_host()[0]); }
}  // namespace

OpacityMask opacity_mask(const std::vector<float>& acc, int h, int w, int H, int W) {
  if (acc.size() != size_t(h) * w) throw Error("opacity_mask: the opacity map is not " + std::to_string(w) + "x" + std::to_string(h));
  OpacityMask m;
  for (int t = 0; t < nn::VggFeatures::kCount; ++t) {
    const int th = H >> t, tw = W >> t;
    const auto r = resize_bilinear(acc, h, w, th, tw);
    std::vector<int32_t> idx;
    for (int i = 0; i < th * tw; ++i)
      if (r[size_t(i)] >= 1e-5f) idx.push_back(i);
    m.count[size_t(t)] = int(idx.size());
    if (!idx.empty()) m.idx[size_t(t)] = Tensor::from_host(idx, {int64_t(idx.size())}, "opacity mask positions");
  }
  return m;
}

Tensor gather_positions(const Tensor& x, const Tensor& idx) {
  if (x.ndim() != 4 || x.dim(0) != 1) throw Error("gather_positions: x must be [1, C, H, W]");
  const int C = int(x.dim(1)), hw = int(x.dim(2) * x.dim(3)), m = int(idx.numel());
  Tensor out({1, C, 1, m}, "masked features");
  host::launch("loss", "gather_positions", {size_t(m), size_t(C)}, x, idx, out, hw, m);
  return out;
}

Tensor scatter_positions(const Tensor& d, const Tensor& idx, int H, int W) {
  const int C = int(d.dim(1)), m = int(idx.numel());
  Tensor dx = Tensor::zeros({1, C, H, W}, "masked features gradient");
  host::launch("loss", "scatter_positions", {size_t(m), size_t(C)}, d, idx, dx, H * W, m);
  return dx;
}

StyleTargets style_targets(const nn::VggFeatures& style) {
  StyleTargets t;
  for (int i = 0; i < nn::VggFeatures::kCount; ++i) {
    if (!style[i].defined()) throw Error(std::string("style targets: the ") + nn::vgg_tap_name(i) + " tap was not computed");
    t[size_t(i)] = nn::style_target(style[i]);
  }
  return t;
}

StyleLossValues style_losses(const nn::VggFeatures& out, const Tensor& content41, const nn::VggFeatures& style,
                             const OpacityMask* mask, const StyleLossWeights& w, nn::VggFeatures* grads) {
  if (mask && mask->empty()) throw Error("style losses: the opacity mask keeps no position");
  return style_losses(out, content41, style_targets(style), mask, w, grads);
}

StyleLossValues style_losses(const nn::VggFeatures& out, const Tensor& content41, const StyleTargets& style,
                             const OpacityMask* mask, const StyleLossWeights& w, nn::VggFeatures* grads) {
  constexpr int K = nn::VggFeatures::kCount;
  if (mask && mask->empty()) throw Error("style losses: the opacity mask keeps no position");
  StyleLossValues v;
  auto sel = [&](const Tensor& x, int t) { return mask ? gather_positions(x, mask->idx[size_t(t)]) : x; };
  auto unsel = [&](const Tensor& d, const Tensor& like, int t) {
    return mask ? scatter_positions(d, mask->idx[size_t(t)], int(like.dim(2)), int(like.dim(3))) : d;
  };
  // Content: relu4_1.
  {
    const Tensor a = sel(out[K - 1], K - 1), b = sel(content41, K - 1);
    v.content = w.content * scalar(nn::mse_forward(a, b));
    if (grads) (*grads)[K - 1] = unsel(nn::mse_backward(a, b, w.content), out[K - 1], K - 1);
  }
  for (int t = 0; t < K; ++t) {
    const Tensor a = sel(out[t], t);
    v.style_tap[size_t(t)] = w.style * scalar(nn::style_loss_forward(a, style[size_t(t)]));
    v.style += v.style_tap[size_t(t)];
    if (grads) {
      Tensor g = unsel(nn::style_loss_backward(a, style[size_t(t)], w.style), out[t], t);
      if ((*grads)[t].defined()) {
        nn::axpby(1.0f, g, 1.0f, (*grads)[t]);
      } else {
        (*grads)[t] = g;
      }
    }
  }
  return v;
}

}  // namespace stylerf::train
