#include "lib/model/map_decoder.hpp"

#include <algorithm>

#include "host/error.hpp"
#include "lib/nn/decoder.hpp"
#include "lib/nn/ops.hpp"

namespace stylerf::model {

using host::Error;

namespace {

// [N, C, H, W] -> [N, C, H + H % 2, W + W % 2], the last row / column repeated: the VGG tail's max-pool
// needs even sides. On the host: inference only, once a frame.
Tensor pad_to_even(const Tensor& x) {
  const int64_t N = x.dim(0), C = x.dim(1), H = x.dim(2), W = x.dim(3), H2 = H + H % 2, W2 = W + W % 2;
  const auto v = x.to_host();
  std::vector<float> o(size_t(N * C * H2 * W2));
  for (int64_t p = 0; p < N * C; ++p)
    for (int64_t y = 0; y < H2; ++y)
      for (int64_t xx = 0; xx < W2; ++xx)
        o[size_t((p * H2 + y) * W2 + xx)] = v[size_t((p * H + std::min(y, H - 1)) * W + std::min(xx, W - 1))];
  return Tensor::from_host(o, {N, C, H2, W2}, "map padded to even sides");
}

Tensor even_sides(const Tensor& map) { return map.dim(2) % 2 || map.dim(3) % 2 ? pad_to_even(map) : map; }

// Channel statistics [1, C] -> [n, C], the row repeated: with the pool's grid phases relu4_1 is n = 4 batch
// blocks of one map, each re-normalised to the same statistics. On the host: two rows of 512 floats.
// x [N, C, H, W] clamped per channel to [lo[c], hi[c]] (both [1, C]). On the host: inference only, once a
// frame (the scene statistics' guard against channels their views never saw vary).
Tensor clamp_channels(const Tensor& x, const Tensor& lo, const Tensor& hi) {
  const int64_t N = x.dim(0), C = x.dim(1), hw = x.dim(2) * x.dim(3);
  if (lo.numel() != C || hi.numel() != C)
    throw Error("style model: the scene's relu4_1 range has " + std::to_string(lo.numel()) + " channels, the map " +
                std::to_string(C));
  auto v = x.to_host();
  const auto l = lo.to_host(), h = hi.to_host();
  for (int64_t n = 0; n < N; ++n)
    for (int64_t c = 0; c < C; ++c)
      for (int64_t i = 0; i < hw; ++i) {
        float& e = v[size_t((n * C + c) * hw + i)];
        e = std::min(std::max(e, l[size_t(c)]), h[size_t(c)]);
      }
  return Tensor::from_host(v, x.shape(), "relu4_1 clamped to the scene's range");
}

nn::ChannelStats repeat_stats(const nn::ChannelStats& s, int64_t n) {
  if (s.mean.dim(0) == n) return s;
  if (s.mean.dim(0) != 1)
    throw Error("style model: relu4_1 statistics for " + std::to_string(s.mean.dim(0)) + " maps cannot serve " +
                std::to_string(n) + " grid phases");
  auto rep = [n](const Tensor& t, const char* name) {
    const auto v = t.to_host();
    std::vector<float> o;
    o.reserve(v.size() * size_t(n));
    for (int64_t i = 0; i < n; ++i) o.insert(o.end(), v.begin(), v.end());
    return Tensor::from_host(o, {n, t.dim(1)}, name);
  };
  return {rep(s.mean, "relu4_1 mean per phase"), rep(s.std, "relu4_1 std per phase")};
}

// Stage 2's decoder, fine-tuned: the paper's. Its parameters are the feature model's, saved with it.
class Stage2MapDecoder : public MapDecoder {
 public:
  StyleDecoderKind kind() const override { return StyleDecoderKind::Stage2; }
  bool needs_fast_profile() const override { return false; }
  void init(StyleModel&) const override {}
  Tensor forward(const StyleModel& m, const Tensor& map, const style::StyleCode*,
                 StyleModel::DecoderCtx* ctx) const override {
    return m.features.decoder.forward(map, ctx ? &ctx->stack : nullptr);
  }
  Tensor backward(StyleModel& m, const StyleModel::DecoderCtx& ctx, const Tensor& drgb, bool need_dx) const override {
    return m.features.decoder.backward(ctx.stack, drgb, need_dx);
  }
  Tensor relu4(const StyleModel&, const Tensor&) const override {
    throw Error("style model: the stage2 decoder has no VGG tail");
  }
  nn::Module& params_of(StyleModel& m) const override { return m.features.decoder; }
  void save(StyleModel&, io::Checkpoint&) const override {}
  void load(StyleModel&, const io::Checkpoint&) const override {}
};

// VGG's frozen relu3_1 -> relu4_1 tail, then AdaIN's decoder ("style.decoder.*").
class VggAdainMapDecoder : public MapDecoder {
 public:
  StyleDecoderKind kind() const override { return StyleDecoderKind::VggAdain; }
  bool needs_fast_profile() const override { return true; }
  bool has_vgg_pool() const override { return true; }
  void init(StyleModel& m) const override {
    m.vgg_tail = nn::VggTail(nn::VggEncoder::load_default());
    m.style_decoder = nn::load_adain_decoder("", "style.decoder.", kGroupStyleDecoder);
  }
  Tensor forward(const StyleModel& m, const Tensor& map, const style::StyleCode* code,
                 StyleModel::DecoderCtx* ctx) const override {
    if (ctx && (map.dim(2) % 2 || map.dim(3) % 2))
      throw Error("style model: the vgg-adain decoder trains on maps with even sides, got " + host::shape_str(map.shape()));
    const Tensor r41 = m.vgg_tail.forward(even_sides(map), ctx ? &ctx->tail : nullptr, m.decoder_phases);
    return m.style_decoder.forward(renormalise(r41, code, ctx), ctx ? &ctx->stack : nullptr, m.decoder_phases);
  }
  Tensor backward(StyleModel& m, const StyleModel::DecoderCtx& ctx, const Tensor& drgb, bool need_dx) const override {
    // Without need_dx (the decoder warm-up) neither the stack's first col2im nor the tail runs.
    const Tensor d41 = m.style_decoder.backward(ctx.stack, drgb, need_dx);
    if (!need_dx) return Tensor();
    return m.vgg_tail.backward(ctx.tail, renormalise_backward(ctx, d41));
  }
  Tensor relu4(const StyleModel& m, const Tensor& map) const override { return m.vgg_tail.forward(even_sides(map), nullptr); }
  nn::Module& params_of(StyleModel& m) const override { return m.style_decoder; }
  void save(StyleModel& m, io::Checkpoint& ck) const override { m.style_decoder.save(ck, ""); }
  void load(StyleModel& m, const io::Checkpoint& ck) const override { m.style_decoder.load(ck, ""); }

 protected:
  // What happens to the tail's relu4_1 before AdaIN's decoder: nothing here.
  virtual Tensor renormalise(const Tensor& r41, const style::StyleCode*, StyleModel::DecoderCtx*) const { return r41; }
  virtual Tensor renormalise_backward(const StyleModel::DecoderCtx&, const Tensor& d41) const { return d41; }
};

// VggAdain with relu4_1 moved to the style's own relu4_1 channel statistics (AdaIN at relu4_1): from the
// map's own statistics in training, from the scene's (model::SceneStyleStats) at inference when the code
// has them. With the grid phases each phase is moved: from its own statistics in training (each is the
// whole map, subsampled), from the scene's at inference (the same map for all four, so no lattice).
class VggAdainRelu4MapDecoder : public VggAdainMapDecoder {
 public:
  StyleDecoderKind kind() const override { return StyleDecoderKind::VggAdainRelu4; }
  bool renormalises_relu4() const override { return true; }

 protected:
  Tensor renormalise(const Tensor& r41, const style::StyleCode* code, StyleModel::DecoderCtx* ctx) const override {
    if (!code || !code->deep_mean.defined() || !code->deep_std.defined())
      throw Error("style model: the vgg-adain-relu4 decoder needs the style's relu4_1 statistics (StyleCode "
                  "deep_mean / deep_std; style::set_relu4_stats)");
    const int64_t n = r41.dim(0);
    const nn::ChannelStats target = repeat_stats({code->deep_mean, code->deep_std}, n);
    const bool scene_stats = !ctx && code->scene_mean.defined() && code->scene_std.defined();
    // With scene statistics a frame is first clamped to the values the scene's pooled views reached.
    const bool guard = scene_stats && code->scene_lo.defined() && code->scene_hi.defined();
    Tensor renormed = scene_stats ? nn::adain_between_stats_forward(
                                        guard ? clamp_channels(r41, code->scene_lo, code->scene_hi) : r41,
                                        repeat_stats({code->scene_mean, code->scene_std}, n), target)
                                  : nn::adain_to_stats_forward(r41, target);
    if (ctx) {
      ctx->relu4 = r41;
      ctx->relu4_target = target;
    }
    return renormed;
  }
  Tensor renormalise_backward(const StyleModel::DecoderCtx& ctx, const Tensor& d41) const override {
    return nn::adain_to_stats_backward(ctx.relu4, ctx.relu4_target, d41);
  }
};

}  // namespace

const MapDecoder& map_decoder_for(StyleDecoderKind kind) {
  static const Stage2MapDecoder stage2;
  static const VggAdainMapDecoder vgg_adain;
  static const VggAdainRelu4MapDecoder vgg_adain_relu4;
  switch (kind) {
    case StyleDecoderKind::Stage2: return stage2;
    case StyleDecoderKind::VggAdain: return vgg_adain;
    case StyleDecoderKind::VggAdainRelu4: return vgg_adain_relu4;
  }
  throw Error("style model: unknown decoder kind");
}

}  // namespace stylerf::model
