#include "lib/nn/vgg.hpp"

#include "host/error.hpp"
#include "lib/nn/weights.hpp"

namespace stylerf::nn {

using host::Error;

namespace {

struct ConvSpec {
  const char* name;
  int cin, cout;
  int adain_index, torchvision_index;  // module index in each nn.Sequential
};
// VGG-19 up to conv4_1. AdaIN's Sequential has conv0 and a ReflectionPad2d before every 3x3 conv, which
// shifts its indices; torchvision's has plain conv/relu/pool modules.
constexpr ConvSpec kConvs[] = {
    {"conv1_1", 3, 64, 2, 0},      {"conv1_2", 64, 64, 5, 2},     {"conv2_1", 64, 128, 9, 5},
    {"conv2_2", 128, 128, 12, 7},  {"conv3_1", 128, 256, 16, 10}, {"conv3_2", 256, 256, 19, 12},
    {"conv3_3", 256, 256, 22, 14}, {"conv3_4", 256, 256, 25, 16}, {"conv4_1", 256, 512, 29, 19},
};
constexpr const char* kTapNames[VggFeatures::kCount] = {"relu1_1", "relu2_1", "relu3_1", "relu4_1"};

// torchvision's VGG expects (rgb - mean) / std with ImageNet statistics.
constexpr float kImagenetMean[3] = {0.485f, 0.456f, 0.406f};
constexpr float kImagenetStd[3] = {0.229f, 0.224f, 0.225f};

}  // namespace

const char* vgg_tap_name(int i) {
  if (i < 0 || i >= VggFeatures::kCount) throw Error("vgg_tap_name: index out of range");
  return kTapNames[i];
}

void VggEncoder::load(const std::string& path) {
  io::SafeTensors st = load_weights(path);
  std::string prefix;
  if (st.has("features.0.weight")) {
    variant_ = VggVariant::Torchvision;
    prefix = "features.";
  } else if (st.has("0.weight") && st.get("0.weight").shape == std::vector<int64_t>{3, 3, 1, 1}) {
    variant_ = VggVariant::AdainNormalised;
  } else if (st.has("0.weight") && st.get("0.weight").shape == std::vector<int64_t>{64, 3, 3, 3}) {
    variant_ = VggVariant::Torchvision;  // torchvision's `features` saved on its own
  } else {
    throw Error(path + ": not VGG-19 weights we know: expected AdaIN's vgg_normalised (\"0.weight\" [3, 3, 1, 1], "
                       "\"2.weight\", ...) or torchvision's VGG-19 (\"features.0.weight\" [64, 3, 3, 3], ...)");
  }
  const bool adain = variant_ == VggVariant::AdainNormalised;
  pad_ = adain ? Padding::Reflect : Padding::Zero;

  std::vector<Conv> convs;
  if (adain) {
    convs.push_back({"conv0", host::Tensor::from_host(st.get("0.weight", {3, 3, 1, 1}).data, {3, 3, 1, 1}, "vgg conv0.w"),
                     host::Tensor::from_host(st.get("0.bias", {3}).data, {3}, "vgg conv0.b"), {}});
  } else {
    // The ImageNet normalisation as a fixed diagonal 1x1 conv, so both variants run the same program.
    std::vector<float> w(9, 0.0f), b(3);
    for (int c = 0; c < 3; ++c) {
      w[c * 3 + c] = 1.0f / kImagenetStd[c];
      b[c] = -kImagenetMean[c] / kImagenetStd[c];
    }
    convs.push_back({"imagenet_normalise", host::Tensor::from_host(w, {3, 3, 1, 1}, "vgg normalise.w"),
                     host::Tensor::from_host(b, {3}, "vgg normalise.b"), {}});
  }
  for (const ConvSpec& c : kConvs) {
    std::string key = prefix + std::to_string(adain ? c.adain_index : c.torchvision_index);
    const auto& w = st.get(key + ".weight", {c.cout, c.cin, 3, 3});
    const auto& b = st.get(key + ".bias", {c.cout});
    convs.push_back({c.name, host::Tensor::from_host(w.data, w.shape, std::string("vgg ") + c.name + ".w"),
                     host::Tensor::from_host(b.data, b.shape, std::string("vgg ") + c.name + ".b"), {}});
  }
  convs_ = std::move(convs);

  // input conv; conv1_1 [relu1_1] conv1_2 pool; conv2_1 [relu2_1] conv2_2 pool;
  // conv3_1 [relu3_1] conv3_2 conv3_3 conv3_4 pool; conv4_1 [relu4_1]
  steps_ = {{0, false, -1}, {1, true, 0}, {2, true, -1},  {-1, false, -1}, {3, true, 1}, {4, true, -1},
            {-1, false, -1}, {5, true, 2}, {6, true, -1}, {7, true, -1},   {8, true, -1}, {-1, false, -1},
            {9, true, 3}};
  path_ = path;
  saved_.clear();
}

std::pair<Tensor, Tensor> VggEncoder::conv_weights(const std::string& name) const {
  for (const Conv& c : convs_)
    if (c.name == name) return {c.w, c.b};
  throw Error("VggEncoder: no conv named '" + name + "'" + (loaded() ? "" : " (no weights loaded)"));
}

VggEncoder VggEncoder::load_default() {
  VggEncoder e;
  e.load(weights_path(kVggWeightsFile));
  return e;
}

VggFeatures VggEncoder::forward(const Tensor& x, int deepest, bool keep_for_backward) {
  if (!loaded()) throw Error("VggEncoder::forward: no weights loaded");
  if (deepest < 1 || deepest > VggFeatures::kCount) throw Error("VggEncoder::forward: deepest must be 1..4");
  if (x.ndim() != 4 || x.dim(1) != 3)
    throw Error("VggEncoder::forward: input must be [N,3,H,W], got " + host::shape_str(x.shape()));
  if (x.dim(2) % 8 || x.dim(3) % 8)
    throw Error("VggEncoder::forward: H and W must be multiples of 8 (three 2x2 poolings), got " +
                host::shape_str(x.shape()));
  saved_.clear();
  VggFeatures out;
  Tensor h = x;
  if (keep_for_backward) saved_.push_back(x);
  for (const Step& s : steps_) {
    if (s.conv < 0) {
      h = maxpool2x2_forward(h);
    } else {
      Conv& c = convs_[s.conv];
      h = conv2d_forward(h, c.w, c.b, s.conv == 0 ? Padding::Zero : pad_, ConvAlgo::Auto, &c.filters);
      if (s.relu) h = relu_forward(h);
    }
    if (keep_for_backward) saved_.push_back(h);
    if (s.tap >= 0) {
      out[s.tap] = h;
      if (s.tap + 1 == deepest) break;
    }
  }
  saved_deepest_ = keep_for_backward ? deepest : 0;
  return out;
}

Tensor VggEncoder::backward(const VggFeatures& grads) {
  if (saved_.empty()) throw Error("VggEncoder::backward: call forward(x, deepest, keep_for_backward = true) first");
  for (int t = saved_deepest_; t < VggFeatures::kCount; ++t)
    if (grads[t].defined())
      throw Error(std::string("VggEncoder::backward: gradient for ") + kTapNames[t] + " but the forward stopped earlier");
  Tensor d;  // gradient w.r.t. the current step's output
  for (int i = int(saved_.size()) - 2; i >= 0; --i) {
    const Step& s = steps_[i];
    if (s.tap >= 0 && grads[s.tap].defined()) {
      host::expect_shape(grads[s.tap], saved_[i + 1].shape(), "VggEncoder::backward", kTapNames[s.tap]);
      if (!d.defined()) {
        d = grads[s.tap];  // read-only below: every step's backward returns a fresh tensor
      } else {
        axpby(1.0f, grads[s.tap], 1.0f, d);  // d is a fresh backward output here, safe to update
      }
    }
    if (!d.defined()) continue;  // nothing flows back from deeper taps yet
    const Tensor& in = saved_[i];
    if (s.conv < 0) {
      d = maxpool2x2_backward(in, d);
    } else {
      if (s.relu) d = relu_backward(saved_[i + 1], d);
      Conv& c = convs_[s.conv];
      d = conv2d_backward(in, c.w, d, s.conv == 0 ? Padding::Zero : pad_, /*need_dx=*/true, /*need_params=*/false,
                          ConvAlgo::Auto, &c.filters)
              .dx;
    }
  }
  if (!d.defined()) throw Error("VggEncoder::backward: all tap gradients are undefined");
  return d;
}

}  // namespace stylerf::nn
