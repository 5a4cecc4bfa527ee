#include "lib/nn/decoder.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <random>

#include "host/error.hpp"
#include "lib/nn/weights.hpp"

namespace stylerf::nn {

using host::Error;

void AdainDecoder::load(const std::string& path) {
  io::SafeTensors st = load_weights(path);
  // Conv modules by their Sequential index: keys "<int>.weight".
  std::map<int, std::string> convs;
  for (const std::string& name : st.names()) {
    auto dot = name.find('.');
    if (dot == std::string::npos || name.substr(dot) != ".weight") continue;
    std::string idx = name.substr(0, dot);
    if (idx.empty() || !std::all_of(idx.begin(), idx.end(), [](unsigned char ch) { return ch >= 0x30 && ch <= 0x39; })) continue;
    convs[std::stoi(idx)] = idx;
  }
  if (convs.empty())
    throw Error(path + ": not a decoder: no \"<index>.weight\" tensors (expected AdaIN's decoder, \"1.weight\" ...)");

  std::vector<Layer> layers;
  for (auto it = convs.begin(); it != convs.end(); ++it) {
    Layer l;
    l.key = it->second;
    const auto& w = st.get(l.key + ".weight");
    if (w.shape.size() != 4 || w.shape[2] != 3 || w.shape[3] != 3)
      throw Error(path + ": tensor '" + l.key + ".weight' has shape " + host::shape_str(w.shape) +
                  ", expected [Cout, Cin, 3, 3]");
    if (!layers.empty() && w.shape[1] != layers.back().w.dim(0))
      throw Error(path + ": tensor '" + l.key + ".weight' has " + std::to_string(w.shape[1]) +
                  " input channels but the previous conv outputs " + std::to_string(layers.back().w.dim(0)));
    const auto& b = st.get(l.key + ".bias", {w.shape[0]});
    l.w = host::Tensor::from_host(w.data, w.shape, "decoder " + l.key + ".weight");
    l.b = host::Tensor::from_host(b.data, b.shape, "decoder " + l.key + ".bias");
    auto next = std::next(it);
    l.relu = next != convs.end();
    if (next != convs.end()) {
      int gap = next->first - it->first;
      if (gap != 3 && gap != 4)
        throw Error(path + ": decoder convs " + it->second + " and " + next->second +
                    " are not separated by (relu, pad) or (relu, upsample, pad): cannot tell the architecture");
      l.upsample = gap == 4;
    }
    layers.push_back(std::move(l));
  }
  if (layers.back().w.dim(0) != 3)
    throw Error(path + ": the last decoder conv outputs " + std::to_string(layers.back().w.dim(0)) +
                " channels, expected 3 (RGB)");
  layers_ = std::move(layers);
  release();
}

AdainDecoder AdainDecoder::load_default() {
  AdainDecoder d;
  d.load(weights_path(kDecoderWeightsFile));
  return d;
}

void AdainDecoder::save(const std::string& path) const {
  std::map<std::string, io::HostTensor> out;
  for (const Layer& l : layers_) {
    out[l.key + ".weight"] = {l.w.shape(), l.w.to_host()};
    out[l.key + ".bias"] = {l.b.shape(), l.b.to_host()};
  }
  io::save_safetensors(path, out, {{"format", "pt"}, {"model", "adain_decoder"}});
}

void AdainDecoder::init_he(uint64_t seed) {
  std::mt19937_64 rng(seed);
  for (Layer& l : layers_) {
    const int64_t fan_in = l.w.dim(1) * l.w.dim(2) * l.w.dim(3);
    std::normal_distribution<float> dist(0.0f, std::sqrt(2.0f / float(fan_in)));
    std::vector<float> w(size_t(l.w.numel()));
    for (float& v : w) v = dist(rng);
    l.w.upload(w);
    l.b.zero();
  }
}

int AdainDecoder::in_channels() const {
  if (!loaded()) throw Error("AdainDecoder: no weights loaded");
  return int(layers_.front().w.dim(1));
}

int AdainDecoder::upsamplings() const {
  return int(std::count_if(layers_.begin(), layers_.end(), [](const Layer& l) { return l.upsample; }));
}

Tensor AdainDecoder::forward(const Tensor& x, bool keep_for_backward) {
  if (!loaded()) throw Error("AdainDecoder::forward: no weights loaded");
  if (x.ndim() != 4 || x.dim(1) != in_channels())
    throw Error("AdainDecoder::forward: input must be [N," + std::to_string(in_channels()) + ",h,w], got " +
                host::shape_str(x.shape()));
  release();
  Tensor h = x;
  for (const Layer& l : layers_) {
    if (keep_for_backward) inputs_.push_back(h);
    h = conv2d_forward(h, l.w, l.b, Padding::Reflect);
    if (l.relu) h = relu_forward(h);
    if (keep_for_backward) relu_out_.push_back(h);
    if (l.upsample) h = upsample2x_forward(h);
  }
  return h;
}

Tensor AdainDecoder::backward(const Tensor& dy, bool need_dx) {
  if (inputs_.size() != layers_.size())
    throw Error("AdainDecoder::backward: call forward(x, keep_for_backward = true) first");
  Tensor d = dy;
  for (int i = int(layers_.size()) - 1; i >= 0; --i) {
    Layer& l = layers_[i];
    if (l.upsample) d = upsample2x_backward(d);
    if (l.relu) d = relu_backward(relu_out_[i], d);
    host::expect_shape(d, relu_out_[i].shape(), "AdainDecoder::backward", "gradient");
    Conv2dGrads g = conv2d_backward(inputs_[i], l.w, d, Padding::Reflect, /*need_dx=*/i > 0 || need_dx,
                                    /*need_params=*/true);
    l.dw = g.dw;
    l.db = g.db;
    d = g.dx;
  }
  return d;
}

}  // namespace stylerf::nn
