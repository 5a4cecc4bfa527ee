#include "lib/model/style_model.hpp"

#include <algorithm>
#include <cmath>

#include "host/error.hpp"
#include "host/gemm.hpp"
#include "lib/model/content_of.hpp"
#include "lib/model/map_decoder.hpp"
#include "lib/nn/layout.hpp"
#include "lib/nn/linear.hpp"
#include "lib/nn/ops.hpp"
#include "lib/style/style_encoder.hpp"

namespace stylerf::model {

using host::Error;
using nlohmann::json;

// ---- SICT head ---------------------------------------------------------------------------------------------
int SictHead::channels() const {
  return style::Sict::kEmbed + (with_components_ ? int(field_.basis.value.dim(0)) : 0);
}

Tensor SictHead::forward(const Tensor& pos, const Tensor& dirs, std::unique_ptr<Context>* ctx) const {
  // Per kept sample: F grid components; SICT of their 256 features (the basis, no bias) without forming
  // them (Sict::forward_factored).
  const Tensor comps = field_.head.forward(pos, dirs, nullptr);
  std::unique_ptr<SictContext> c;
  if (ctx) c = std::make_unique<SictContext>();
  Tensor y = sict_.forward_factored(comps, field_.basis.value, training_, c ? &c->sict : nullptr);
  if (ctx) *ctx = std::move(c);
  return with_components_ ? nn::concat_columns(y, comps) : y;
}

void SictHead::backward(const Context& ctx, const Tensor& dvalues) {
  const auto& c = dynamic_cast<const SictContext&>(ctx);
  // The components come from the frozen field: only SICT's columns carry a gradient.
  sict_.backward(c.sict, with_components_ ? nn::take_columns(dvalues, 0, style::Sict::kEmbed) : dvalues, false);
}

// ---- model -------------------------------------------------------------------------------------------------
StyleDecoderKind parse_style_decoder(const std::string& s) {
  if (s == "stage2") return StyleDecoderKind::Stage2;
  if (s == "vgg-adain") return StyleDecoderKind::VggAdain;
  if (s == "vgg-adain-relu4") return StyleDecoderKind::VggAdainRelu4;
  throw host::SettingError("style_decoder", "must be stage2, vgg-adain or vgg-adain-relu4, got '" + s + "'");
}

const char* style_decoder_name(StyleDecoderKind k) {
  switch (k) {
    case StyleDecoderKind::Stage2: return "stage2";
    case StyleDecoderKind::VggAdain: return "vgg-adain";
    case StyleDecoderKind::VggAdainRelu4: return "vgg-adain-relu4";
  }
  return "?";
}

StyleModel StyleModel::create(FeatureModel features, style::SictMode sict_mode, bool dst_bias, uint64_t seed,
                              StyleDecoderKind decoder, bool content_skip) {
  if (content_skip && sict_mode != style::SictMode::VolumeAdaptive)
    throw Error("style model: the content skip normalises with SICT's running statistics, which only the "
                "volume-adaptive SICT keeps (this one is " + std::string(style::sict_mode_name(sict_mode)) + ")");
  const MapDecoder& d = map_decoder_for(decoder);
  if (d.needs_fast_profile() && features.profile != DecoderProfile::Fast)
    throw Error("style model: the " + std::string(style_decoder_name(decoder)) + " style decoder needs the fast profile (maps at relu3_1's 1/4 resolution); "
                "this feature model is " + std::string(decoder_profile_name(features.profile)));
  StyleModel m;
  m.map_decoder = &d;
  d.init(m);
  m.features = std::move(features);
  m.inference_step_ratio = default_inference_step_ratio(m.features.geo);
  // Samples with weight below 1e-3 are dropped before SICT (the authors' style stage): fewer points, and
  // SICT's batch statistics describe the visible surface rather than the faint haze around it.
  m.features.geo.weight_threshold = std::max(m.features.geo.weight_threshold, kStyleWeightThreshold);
  for (nn::Param* p : m.features.decoder.params()) p->group = kGroupStyleDecoder;
  m.sict = style::Sict::create(sict_mode, kGroupStylizer, seed * 2 + 1, "style.sict.");
  m.dst = style::Dst::create(dst_bias, kGroupStylizer, seed * 2 + 2, "style.dst.");
  m.content_skip = content_skip;
  if (content_skip) m.skip = style::ContentSkip::create(kGroupStylizer, "style.skip.");
  return m;
}

int StyleModel::content_channels() const {
  return style::Sict::kEmbed + (content_skip ? int(features.field.basis.value.dim(0)) : 0);
}

Tensor StyleModel::transform(const Tensor& c, const Tensor& kept_acc, const style::StyleCode& code,
                             Context* ctx) const {
  if (!content_skip) return dst.apply(c, kept_acc, code, ctx ? &ctx->dst : nullptr);
  if (!c.defined() || c.ndim() != 2 || c.dim(1) != content_channels())
    throw Error("style model: content rows must be [R, " + std::to_string(content_channels()) + "] (SICT's " +
                std::to_string(style::Sict::kEmbed) + " and the field's components), got " +
                (c.defined() ? host::shape_str(c.shape()) : std::string("undefined")));
  Tensor y = dst.apply(nn::take_columns(c, 0, style::Sict::kEmbed), kept_acc, code, ctx ? &ctx->dst : nullptr);
  const style::ContentSkip::Input in{c, style::Sict::kEmbed, kept_acc, features.field.basis.value,
                                     sict.running_mean.value, sict.running_var.value};
  skip.forward_add(in, code.std, y, ctx ? &ctx->skip : nullptr);
  return y;
}

Tensor StyleModel::stylised_rows(const Tensor& c, const Tensor& kept_acc, const style::StyleCode& code) const {
  Tensor y = transform(c, kept_acc, code, nullptr);
  if (strength < 1.0f) {  // y = s y + (1 - s) Z B: the components after SICT's columns through the basis
    const Tensor& B = features.field.basis.value;
    const int R = int(c.dim(0)), F = int(B.dim(0)), C = style::ContentSkip::kChannels;
    host::gemm(host::Trans::No, host::Trans::No, R, C, F, 1.0f - strength, c.mem(), size_t(style::Sict::kEmbed),
               int(c.dim(1)), B.mem(), 0, C, strength, y.mem(), 0, C);
  }
  return y;
}

void StyleModel::blend_at_strength(Tensor& y, const Tensor& z) const {
  if (strength < 1.0f) nn::axpby(1.0f - strength, z, strength, y);
}

void StyleModel::set_strength(float s) {
  if (!(s >= 0.0f && s <= 1.0f)) throw Error("style model: the strength must be in [0, 1], got " + std::to_string(s));
  if (s < 1.0f && !content_skip)
    throw Error("style model: a strength below 1 blends in the composited features, which only a model with the "
                "content skip renders (this one is the paper's module)");
  strength = s;
}

Tensor StyleModel::transform_features(const Tensor& c, const Tensor& z, const Tensor& acc, const Tensor& mean,
                                      const Tensor& var, const style::StyleCode& code, Context* ctx) const {
  Tensor y = dst.apply(c, acc, code, ctx ? &ctx->dst : nullptr);
  if (!content_skip) return y;
  const style::ContentSkip::Input in{z, 0, acc, Tensor(), mean, var};  // the identity basis
  skip.forward_add(in, code.std, y, ctx ? &ctx->skip : nullptr);
  return y;
}

style::Dst::ApplyGrads StyleModel::transform_backward(Context& ctx, const Tensor& dy) {
  style::Dst::ApplyGrads g = dst.apply_backward(ctx.dst, dy, true);
  if (content_skip) nn::axpby(1.0f, skip.backward(ctx.skip, dy), 1.0f, g.dstd);
  return g;
}

StyleModel::Content StyleModel::render_content(const Tensor& origins, const Tensor& dirs, bool training,
                                               uint32_t jitter_seed, Context* ctx) const {
  if (training && !ctx) throw Error("style model: a training render needs a context");
  // The head holds a mutable reference for backward; forward itself changes nothing.
  auto head = std::make_unique<SictHead>(features.field, const_cast<style::Sict&>(sict), training, content_skip);
  RayOptions opt;
  opt.jitter = training;
  opt.seed = jitter_seed;
  const RayResult r = render_rays(features.geo, *head, origins, dirs, opt, ctx ? &ctx->rays : nullptr);
  if (ctx) ctx->head = std::move(head);
  Content content = content_of(r);
  content.background = features.field.shell_term(features.geo, origins, dirs, content.acc);
  return content;
}

Tensor StyleModel::decode_styled(const Content& content, const style::StyleCode& code, int h, int w,
                                 Context* ctx) const {
  if (int64_t(h) * w != content.c.dim(0))
    throw Error("style model: a " + std::to_string(w) + "x" + std::to_string(h) + " map needs " +
                std::to_string(int64_t(h) * w) + " rays, got " + std::to_string(content.c.dim(0)));
  return decode_rows(ctx ? transform(content.c, content.kept_acc, code, ctx) : stylised_rows(content.c, content.kept_acc, code),
                     content.acc, h, w, &code, ctx, content.background);
}

Tensor StyleModel::decode_rows(Tensor y, const Tensor& acc, int h, int w, const style::StyleCode* code,
                               Context* ctx, const Tensor& background) const {
  // Empty space keeps stage 2's (unstyled) background feature, which the decoder learned to draw as the
  // background colour; the masked losses never look there.
  if (features.field.background.value.defined())
    render::background_forward(y, acc, features.field.background.value);
  if (background.defined()) nn::axpby(1.0f, background, 1.0f, y);
  const Tensor map = nn::rows_to_image(y, h, w);
  if (ctx) {
    ctx->h = h;
    ctx->w = w;
  }
  return decode_map(map, code, ctx ? &ctx->decoder : nullptr);
}

StyleDecoderKind StyleModel::decoder_kind() const { return map_decoder->kind(); }

Tensor StyleModel::decode_map(const Tensor& map, const style::StyleCode* code, DecoderCtx* ctx) const {
  return map_decoder->forward(*this, map, code, ctx);
}

Tensor StyleModel::decode_map_backward(const DecoderCtx& ctx, const Tensor& drgb, bool need_dx) {
  return map_decoder->backward(*this, ctx, drgb, need_dx);
}

Tensor StyleModel::relu4_of(const Content& content, const style::StyleCode& code, int h, int w) const {
  Tensor y = stylised_rows(content.c, content.kept_acc, code);
  if (features.field.background.value.defined()) render::background_forward(y, content.acc, features.field.background.value);
  if (content.background.defined()) nn::axpby(1.0f, content.background, 1.0f, y);
  return map_decoder->relu4(*this, nn::rows_to_image(y, h, w));
}

std::vector<nn::Param*> StyleModel::decoder_params() { return map_decoder->params_of(*this).params(); }

style::Dst::ApplyGrads StyleModel::backward(Context& ctx, const Tensor& drgb) {
  const Tensor dmap = decode_map_backward(ctx.decoder, drgb, true);
  style::Dst::ApplyGrads g = transform_backward(ctx, nn::rows_to_image_backward(dmap));
  const Tensor dvalues = content_skip ? nn::take_columns_backward(g.dc, 0, content_channels()) : g.dc;
  render_rays_backward(features.geo, *ctx.head, ctx.rays, dvalues, Tensor(), nullptr);
  return g;
}

namespace {
// SICT then DST per kept sample (256 channels out): the per-point order of the deferred-vs-per-point proof.
class PerPointStyledHead : public SampleHead {
 public:
  PerPointStyledHead(const FeatureField& field, const style::Sict& sict, const style::Dst& dst,
                     const style::StyleCode& code)
      : sict_head_(field, const_cast<style::Sict&>(sict), false), dst_(dst), code_(code) {}
  int channels() const override { return style::Dst::kChannels; }
  Tensor forward(const Tensor& pos, const Tensor& dirs, std::unique_ptr<Context>*) const override {
    return dst_.apply_per_point(sict_head_.forward(pos, dirs, nullptr), code_);
  }
  void backward(const Context&, const Tensor&) override { throw Error("per-point styled head: inference only"); }
  void collect_params(std::vector<nn::Param*>&) override {}

 private:
  SictHead sict_head_;
  const style::Dst& dst_;
  const style::StyleCode& code_;
};
}  // namespace

RayResult StyleModel::render_styled_per_point(const Tensor& origins, const Tensor& dirs,
                                              const style::StyleCode& code) const {
  if (content_skip) throw Error("style model: the per-point order is DST's alone (this model has the content skip)");
  const PerPointStyledHead head(features.field, sict, dst, code);
  return render_rays(features.geo, head, origins, dirs, RayOptions{}, nullptr);
}

void StyleModel::collect_params(std::vector<nn::Param*>& out) {
  sict.collect_params(out);
  dst.collect_params(out);
  if (content_skip) skip.collect_params(out);
  map_decoder->params_of(*this).collect_params(out);
}

void StyleModel::collect_buffers(std::vector<nn::StateBuffer*>& out) { sict.collect_buffers(out); }

void StyleModel::save(io::Checkpoint& ck) {
  features.save(ck);  // geometry, field, decoder ("model.*")
  sict.save(ck, "");
  dst.save(ck, "");
  if (content_skip) skip.save(ck, "");
  map_decoder->save(*this, ck);
  ck.meta["style_model"] = {
      {"sict", style::sict_mode_name(sict.mode)},
      {"dst_bias", dst.bias},
      {"decoder", style_decoder_name(decoder_kind())},
      {"inference_supersample", inference_supersample == kQuincunx ? json(supersample_name(kQuincunx))
                                                                   : json(inference_supersample)},
      {"decoder_phases", decoder_phases},
      {"content_skip", content_skip},
      {"strength", strength}};
}

StyleModel StyleModel::load(const io::Checkpoint& ck) {
  if (!ck.meta.contains("style_model"))
    throw Error("checkpoint " + ck.path + " has no style model (kind '" + ck.kind +
                "'; train one with `stylerf train-style`)");
  style::SictMode mode;
  bool bias = true;
  StyleDecoderKind decoder = StyleDecoderKind::Stage2;
  int supersample = 1;
  bool phases = false, content_skip = false;
  float strength = 1.0f;
  try {
    const json& sm = ck.meta.at("style_model");
    mode = style::parse_sict_mode(sm.at("sict").get<std::string>());
    bias = sm.at("dst_bias").get<bool>();
    decoder = parse_style_decoder(sm.value("decoder", std::string("stage2")));  // absent before the option existed
    if (sm.contains("inference_supersample")) {  // absent before recipes set it; a name or n
      const json& v = sm.at("inference_supersample");
      supersample = v.is_string() ? parse_supersample(v.get<std::string>()) : v.get<int>();
    }
    phases = sm.value("decoder_phases", false);           // absent before the option existed
    content_skip = sm.value("content_skip", false);       // absent before the content skip existed
    strength = sm.value("strength", 1.0f);                // absent before the strength existed
  } catch (const json::exception& e) {
    throw Error("checkpoint " + ck.path + ": bad style-model metadata (" + e.what() + ")");
  } catch (const Error& e) {
    throw Error("checkpoint " + ck.path + ": " + e.what());
  }
  StyleModel m = create(FeatureModel::load(ck), mode, bias, 0, decoder, content_skip);
  m.sict.load(ck, "");
  m.dst.load(ck, "");
  if (content_skip) m.skip.load(ck, "");
  m.map_decoder->load(m, ck);
  if (!valid_supersample(supersample))
    throw Error("checkpoint " + ck.path + ": style_model.inference_supersample " + std::to_string(supersample) +
                " is outside 1.." + std::to_string(kMaxSupersample) + " (or quincunx)");
  m.inference_supersample = supersample;
  if (phases && !m.map_decoder->has_vgg_pool())
    throw Error("checkpoint " + ck.path + ": style_model.decoder_phases is set for the " +
                style_decoder_name(decoder) + " decoder (only the vgg-adain decoders have them)");
  m.decoder_phases = phases;
  try {
    m.set_strength(strength);
  } catch (const Error& e) {
    throw Error("checkpoint " + ck.path + ": " + e.what());
  }
  m.features.decoder.freeze();
  if (!m.style_decoder.empty()) m.style_decoder.freeze();
  return m;
}

Tensor style_rows(const nn::VggFeatures& taps) {
  if (!taps[2].defined()) throw Error("style_rows: the relu3_1 tap was not computed");
  return nn::image_to_rows(taps[2]);
}

style::StyleCode StyleModel::style_code(const nn::VggFeatures& taps, style::Dst::StyleContext* ctx) const {
  style::StyleCode code = dst.style_code(style_rows(taps), ctx);
  if (map_decoder->renormalises_relu4()) {
    if (!taps[3].defined())
      throw Error("style model: the vgg-adain-relu4 decoder needs the style's relu4_1 tap (VGG to depth 4)");
    style::set_relu4_stats(code, taps[3]);
  }
  return code;
}

}  // namespace stylerf::model
