#include "lib/nn/vgg_tail.hpp"

#include "host/error.hpp"

namespace stylerf::nn {

using host::Error;

namespace {
constexpr int kPoolBefore = 3;  // the pool runs before convs_[3] (conv4_1)
}

VggTail::VggTail(const VggEncoder& vgg) {
  if (!vgg.loaded()) throw Error("VggTail: the encoder has no weights loaded");
  for (const char* name : {"conv3_2", "conv3_3", "conv3_4", "conv4_1"}) {
    auto [w, b] = vgg.conv_weights(name);
    convs_.push_back({w, b, {}});
  }
  pad_ = vgg.padding();
}

Tensor VggTail::forward(const Tensor& x, Ctx* ctx, bool phases) const {
  if (!loaded()) throw Error("VggTail::forward: no weights");
  const int64_t cin = convs_[0].w.dim(1);
  if (x.ndim() != 4 || x.dim(1) != cin || x.dim(2) < 2 || x.dim(3) < 2 || x.dim(2) % 2 || x.dim(3) % 2)
    throw Error("VggTail::forward: relu3_1 features must be [N," + std::to_string(cin) +
                ",H,W] with H and W even (one 2x2 pool), got " + host::shape_str(x.shape()));
  if (ctx) {
    ctx->inputs.clear();
    ctx->outputs.clear();
    ctx->phases = phases;
  }
  Tensor h = x;
  for (int i = 0; i < int(convs_.size()); ++i) {
    if (i == kPoolBefore) h = phases ? maxpool2x2_phases_forward(h) : maxpool2x2_forward(h);
    if (ctx) ctx->inputs.push_back(h);
    const Conv& c = convs_[size_t(i)];
    h = relu_forward(conv2d_forward(h, c.w, c.b, pad_, ConvAlgo::Auto, &c.filters));
    if (ctx) ctx->outputs.push_back(h);
  }
  return h;
}

Tensor VggTail::backward(const Ctx& ctx, const Tensor& dy) const {
  if (ctx.inputs.size() != convs_.size()) throw Error("VggTail::backward: call forward with a context first");
  host::expect_shape(dy, ctx.outputs.back().shape(), "VggTail::backward", "dy");
  Tensor d = dy;
  for (int i = int(convs_.size()) - 1; i >= 0; --i) {
    const Tensor& in = ctx.inputs[size_t(i)];
    d = relu_backward(ctx.outputs[size_t(i)], d);
    const Conv& c = convs_[size_t(i)];
    d = conv2d_backward(in, c.w, d, pad_, /*need_dx=*/true, /*need_params=*/false, ConvAlgo::Auto, &c.filters).dx;
    if (i == kPoolBefore) {
      const Tensor& pooled_from = ctx.outputs[size_t(i) - 1];
      d = ctx.phases ? maxpool2x2_phases_backward(pooled_from, d) : maxpool2x2_backward(pooled_from, d);
    }
  }
  return d;
}

}  // namespace stylerf::nn
