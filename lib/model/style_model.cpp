#include "lib/model/style_model.hpp"

#include <algorithm>
#include <cmath>

#include "host/error.hpp"
#include "host/gemm.hpp"
#include "lib/model/block_refine.hpp"
#include "lib/model/map_decoder.hpp"
#include "lib/model/opacity_head.hpp"
#include "lib/nn/layout.hpp"
#include "lib/nn/linear.hpp"
#include "lib/nn/ops.hpp"
#include "lib/scene/rays.hpp"
#include "lib/style/style_encoder.hpp"

namespace stylerf::model {

using host::Error;
using nlohmann::json;

// ---- SICT head ---------------------------------------------------------------------------------------------
Tensor SictHead::forward(const Tensor& pos, const Tensor& dirs, std::unique_ptr<Context>* ctx) const {
  // Per kept sample: F grid components; SICT of their 256 features (the basis, no bias) without forming
  // them (Sict::forward_factored).
  const Tensor comps = field_.head.forward(pos, dirs, nullptr);
  if (!ctx) return sict_.forward_factored(comps, field_.basis.value, training_, nullptr);
  auto c = std::make_unique<SictContext>();
  Tensor y = sict_.forward_factored(comps, field_.basis.value, training_, &c->sict);
  *ctx = std::move(c);
  return y;
}

void SictHead::backward(const Context& ctx, const Tensor& dvalues) {
  const auto& c = dynamic_cast<const SictContext&>(ctx);
  sict_.backward(c.sict, dvalues, false);
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
                              StyleDecoderKind decoder) {
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
  return m;
}

namespace {
// A renderer result (RayResult or GroupResult: the same per-ray fields) as the content the style stage reads.
template <class Result>
StyleModel::Content content_of(const Result& r) {
  StyleModel::Content c;
  c.c = r.value;
  c.kept_acc = r.kept_acc;
  c.acc = r.acc;
  c.depth = r.depth;
  c.samples = r.samples;
  c.kept = r.kept;
  return c;
}
}  // namespace

StyleModel::Content StyleModel::render_content(const Tensor& origins, const Tensor& dirs, bool training,
                                               uint32_t jitter_seed, Context* ctx) const {
  if (training && !ctx) throw Error("style model: a training render needs a context");
  // The head holds a mutable reference for backward; forward itself changes nothing.
  auto head = std::make_unique<SictHead>(features.field, const_cast<style::Sict&>(sict), training);
  RayOptions opt;
  opt.jitter = training;
  opt.seed = jitter_seed;
  const RayResult r = render_rays(features.geo, *head, origins, dirs, opt, ctx ? &ctx->rays : nullptr);
  if (ctx) ctx->head = std::move(head);
  return content_of(r);
}

Tensor StyleModel::decode_styled(const Content& content, const style::StyleCode& code, int h, int w,
                                 Context* ctx) const {
  if (int64_t(h) * w != content.c.dim(0))
    throw Error("style model: a " + std::to_string(w) + "x" + std::to_string(h) + " map needs " +
                std::to_string(int64_t(h) * w) + " rays, got " + std::to_string(content.c.dim(0)));
  return decode_rows(dst.apply(content.c, content.kept_acc, code, ctx ? &ctx->dst : nullptr), content.acc, h, w, &code,
                     ctx);
}

Tensor StyleModel::decode_rows(Tensor y, const Tensor& acc, int h, int w, const style::StyleCode* code,
                               Context* ctx) const {
  // Empty space keeps stage 2's (unstyled) background feature, which the decoder learned to draw as the
  // background colour; the masked losses never look there.
  if (features.field.background.value.defined())
    render::background_forward(y, acc, features.field.background.value);
  const Tensor map = nn::rows_to_image(y, h, w);
  if (ctx) {
    ctx->h = h;
    ctx->w = w;
  }
  return decode_map(map, code, ctx ? &ctx->decoder : nullptr);
}

namespace {
// A per-block map [h][w] at the image's pixels [cam_h][cam_w], bilinear between the block centres (block
// j's ray passes through pixel coordinate s (j + 0.5)), clamped at the edges.
std::vector<float> upsample_blocks(const std::vector<float>& v, int w, int h, int s, int cam_w, int cam_h) {
  auto at = [&](int x, int y) { return v[size_t(std::clamp(y, 0, h - 1)) * w + size_t(std::clamp(x, 0, w - 1))]; };
  std::vector<float> out(size_t(cam_w) * cam_h);
  for (int y = 0; y < cam_h; ++y)
    for (int x = 0; x < cam_w; ++x) {
      const float fx = (x + 0.5f) / float(s) - 0.5f, fy = (y + 0.5f) / float(s) - 0.5f;
      const int x0 = int(std::floor(fx)), y0 = int(std::floor(fy));
      const float u = fx - x0, t = fy - y0;
      out[size_t(y) * cam_w + x] = (1 - u) * (1 - t) * at(x0, y0) + u * (1 - t) * at(x0 + 1, y0) +
                                   (1 - u) * t * at(x0, y0 + 1) + u * t * at(x0 + 1, y0 + 1);
    }
  return out;
}
}  // namespace

StyleDecoderKind StyleModel::decoder_kind() const { return map_decoder->kind(); }

Tensor StyleModel::decode_map(const Tensor& map, const style::StyleCode* code, DecoderCtx* ctx) const {
  return map_decoder->forward(*this, map, code, ctx);
}

Tensor StyleModel::decode_map_backward(const DecoderCtx& ctx, const Tensor& drgb, bool need_dx) {
  return map_decoder->backward(*this, ctx, drgb, need_dx);
}

Tensor StyleModel::relu4_of(const Content& content, const style::StyleCode& code, int h, int w) const {
  Tensor y = dst.apply(content.c, content.kept_acc, code, nullptr);
  if (features.field.background.value.defined()) render::background_forward(y, content.acc, features.field.background.value);
  return map_decoder->relu4(*this, nn::rows_to_image(y, h, w));
}

std::vector<nn::Param*> StyleModel::decoder_params() { return map_decoder->params_of(*this).params(); }

style::Dst::ApplyGrads StyleModel::backward(Context& ctx, const Tensor& drgb) {
  const Tensor dmap = decode_map_backward(ctx.decoder, drgb, true);
  style::Dst::ApplyGrads g = dst.apply_backward(ctx.dst, nn::rows_to_image_backward(dmap), true);
  render_rays_backward(features.geo, *ctx.head, ctx.rays, g.dc, Tensor(), nullptr);
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
  const PerPointStyledHead head(features.field, sict, dst, code);
  return render_rays(features.geo, head, origins, dirs, RayOptions{}, nullptr);
}

std::string supersample_name(int n) {
  if (n == kQuincunx) return "quincunx";
  return n == 1 ? "1" : std::to_string(n) + "x" + std::to_string(n);
}

int default_inference_supersample(int map_w, int map_h, bool ndc) {
  return ndc && std::max(map_w, map_h) >= kQuincunxMapSide ? kQuincunx : 3;
}

int parse_supersample(const std::string& text) {
  if (text == "quincunx" || text == "q") return kQuincunx;
  // "n" or supersample_name's "nxn", so that every name written (metrics, tables) reads back.
  const bool square = text.size() == 3 && text[1] == 'x' && text[2] == text[0];
  if ((text.size() == 1 || square) && text[0] >= '1' && text[0] - '0' <= kMaxSupersample) return text[0] - '0';
  throw Error("supersample '" + text + "': expected 1.." + std::to_string(kMaxSupersample) +
              " (n x n rays a block) or quincunx");
}

StyleModel::CameraContent StyleModel::render_camera_content(const scene::Scene& scene, const scene::Camera& cam,
                                                            int chunk, const RegionHead* region, int supersample,
                                                            float refine_contrast, float merge_kept_per_ray) const {
  if (chunk < 1) throw Error("style model: chunk must be >= 1");
  if (!valid_supersample(supersample))
    throw Error("style model: supersample must be in 1.." + std::to_string(kMaxSupersample) + " or quincunx, got " +
                std::to_string(supersample));
  const Geometry geo = inference_geometry();
  const SictHead centre_head(features.field, const_cast<style::Sict&>(sict), false);
  const scene::Camera map_cam = strided_camera(cam, stride());  // the map's size
  int w = map_cam.width, h = map_cam.height;
  const int64_t n = int64_t(w) * h;
  const int E = style::Sict::kEmbed;
  // Sums over the sub-rays of each block; divided by their count at the end.
  std::vector<double> c(size_t(n) * E, 0.0), kept_acc(size_t(n), 0.0), acc(size_t(n), 0.0), depth(size_t(n), 0.0);
  std::vector<float> acc_lo(size_t(n), 1.0f), acc_hi(size_t(n), 0.0f);  // over each block's sub-rays
  std::vector<double> inside(region ? size_t(n) : 0, 0.0);
  std::vector<double> rays_in(size_t(n), 1.0);  // sub-rays summed per block (their weights)
  CameraContent out;
  out.width = w;
  out.height = h;
  const ShadeFn shade = [&](const Tensor& comps) {
    return sict.forward_factored(comps, features.field.basis.value, false, nullptr);
  };
  // Whether shade_rays shades per depth slab (render_ray_groups of one ray): decided by its first call, whose
  // rays are shaded per sample; the later calls merge when that call kept >= merge_kept_per_ray samples a
  // ray. On soft geometry SICT on every kept sample is most of a centre ray's cost.
  bool first_call = true, slab_rays = false;
  // One renderer call on the R rays o, d ([R, 3] on the host), each ray its own: their content and, with a
  // region, their region indicator composited with the same weights (the same kept samples, no jitter).
  struct Shaded {
    Content part;
    std::vector<float> inside;
  };
  auto shade_rays = [&](const std::vector<float>& o, const std::vector<float>& d, int64_t R) {
    const Tensor origins = Tensor::from_host(o, {R, 3}, "render origins");
    const Tensor dirs = Tensor::from_host(d, {R, 3}, "render directions");
    Shaded s;
    s.part = slab_rays ? content_of(render_ray_groups(geo, features.field.head, shade, E, origins, dirs, 1, kMergeSteps))
                       : content_of(render_rays(geo, centre_head, origins, dirs, RayOptions{}, nullptr));
    if (first_call) {
      first_call = false;
      slab_rays = double(s.part.kept) >= double(merge_kept_per_ray) * double(R);
      out.slab_shaded = slab_rays;
    }
    out.content.samples += s.part.samples;
    out.content.kept += s.part.kept;
    if (region) s.inside = render_rays(geo, *region, origins, dirs, RayOptions{}, nullptr).value.to_host();
    return s;
  };
  // Renders the blocks `which` (all when empty) at sub-position (fx, fy) of each block and adds into the sums.
  auto add_rays = [&](float fx, float fy, const std::vector<int64_t>& which) {
    const scene::Rays rays = block_rays(scene, cam, stride(), w, h, fx, fy);
    const int64_t count = which.empty() ? n : int64_t(which.size());
    for (int64_t b = 0; b < count; b += chunk) {
      const int64_t R = std::min<int64_t>(chunk, count - b);
      auto block = [&](int64_t r) { return which.empty() ? b + r : which[size_t(b + r)]; };
      std::vector<float> o(size_t(3 * R)), d(size_t(3 * R));
      for (int64_t r = 0; r < R; ++r)
        for (int j = 0; j < 3; ++j) {
          o[size_t(3 * r + j)] = rays.origins[size_t(3 * block(r) + j)];
          d[size_t(3 * r + j)] = rays.directions[size_t(3 * block(r) + j)];
        }
      const Shaded s = shade_rays(o, d, R);
      const auto pc = s.part.c.to_host(), pk = s.part.kept_acc.to_host(), pa = s.part.acc.to_host();
      const auto pd = s.part.depth.to_host();
      for (int64_t r = 0; r < R; ++r) {
        const size_t i = size_t(block(r));
        for (int e = 0; e < E; ++e) c[i * E + size_t(e)] += pc[size_t(r * E + e)];
        kept_acc[i] += pk[size_t(r)];
        acc[i] += pa[size_t(r)];
        acc_lo[i] = std::min(acc_lo[i], pa[size_t(r)]);
        acc_hi[i] = std::max(acc_hi[i], pa[size_t(r)]);
        depth[i] += pd[size_t(r)];
        if (region) inside[i] += s.inside[size_t(r)];
      }
    }
  };
  // The blocks `which` as groups of their n x n sub-rays (render_ray_groups): the geometry per sub-ray, SICT
  // once per depth slab of the block on the weight-averaged field components of the sub-rays' samples there.
  // skip_centre: odd n, whose centre sub-ray the first pass rendered already (kept as it is).
  auto add_groups = [&](const std::vector<int64_t>& which, bool skip_centre) {
    std::vector<scene::Rays> sub;  // per sub-position, the rays of every block
    for (int sy = 0; sy < supersample; ++sy)
      for (int sx = 0; sx < supersample; ++sx)
        if (!(skip_centre && sx == supersample / 2 && sy == supersample / 2))
          sub.push_back(block_rays(scene, cam, stride(), w, h, (sx + 0.5f) / float(supersample),
                                   (sy + 0.5f) / float(supersample)));
    const int G = int(sub.size());
    const int64_t per_call = std::max<int64_t>(1, chunk / G);  // blocks a call
    const int64_t count = int64_t(which.size());
    for (int64_t b = 0; b < count; b += per_call) {
      const int64_t B = std::min<int64_t>(per_call, count - b);
      std::vector<float> o(size_t(3 * B * G)), d(size_t(3 * B * G));
      for (int64_t r = 0; r < B; ++r)
        for (int q = 0; q < G; ++q)
          for (int j = 0; j < 3; ++j) {
            const size_t from = size_t(3 * which[size_t(b + r)] + j), to = size_t(3 * (r * G + q) + j);
            o[to] = sub[size_t(q)].origins[from];
            d[to] = sub[size_t(q)].directions[from];
          }
      const Tensor origins = Tensor::from_host(o, {B * G, 3}, "render origins");
      const Tensor dirs = Tensor::from_host(d, {B * G, 3}, "render directions");
      const GroupResult part = render_ray_groups(geo, features.field.head, shade, E, origins, dirs, G, kMergeSteps);
      const auto pc = part.value.to_host(), pk = part.kept_acc.to_host(), pa = part.acc.to_host();
      const auto pd = part.depth.to_host();
      std::vector<float> in;
      if (region) in = render_rays(geo, *region, origins, dirs, RayOptions{}, nullptr).value.to_host();
      for (int64_t r = 0; r < B; ++r) {
        const size_t i = size_t(which[size_t(b + r)]);
        // The group's value is already its G sub-rays' mean; the sums here are divided by n^2 at the end.
        for (int e = 0; e < E; ++e) c[i * E + size_t(e)] += double(G) * pc[size_t(r * E + e)];
        kept_acc[i] += double(G) * pk[size_t(r)];
        for (int q = 0; q < G; ++q) {
          const size_t ray = size_t(r * G + q);
          acc[i] += pa[ray];
          acc_lo[i] = std::min(acc_lo[i], pa[ray]);
          acc_hi[i] = std::max(acc_hi[i], pa[ray]);
          depth[i] += pd[ray];
          if (region) inside[i] += in[ray];
        }
      }
      out.content.samples += part.samples;
      out.content.kept += part.kept;
    }
  };
  // Quincunx: a refined block is its centre ray (weight 4) plus the rays through its four corners (weight 1
  // each), the corners shared with the neighbouring blocks: one ray more a block instead of n^2 - 1.
  const bool quincunx = supersample == kQuincunx;
  auto add_corners = [&](const std::vector<int64_t>& which) {
    const int cw = w + 1, chh = h + 1, s = stride();
    std::vector<int64_t> corner_id(size_t(cw) * chh, -1), corners;
    for (int64_t b : which) {
      const int bx = int(b % w), by = int(b / w);
      for (int dy = 0; dy <= 1; ++dy)
        for (int dx = 0; dx <= 1; ++dx) {
          const size_t k = size_t(by + dy) * cw + size_t(bx + dx);
          if (corner_id[k] < 0) {
            corner_id[k] = int64_t(corners.size());
            corners.push_back(int64_t(k));
          }
        }
    }
    const int64_t K = int64_t(corners.size());
    std::vector<float> cc(size_t(K) * E), ck(static_cast<size_t>(K)), ca(static_cast<size_t>(K)), cd(static_cast<size_t>(K)),
        ci(region ? size_t(K) : 0);
    for (int64_t b = 0; b < K; b += chunk) {
      const int64_t R = std::min<int64_t>(chunk, K - b);
      std::vector<float> o(size_t(3 * R)), d(size_t(3 * R));
      for (int64_t r = 0; r < R; ++r) {
        const int64_t k = corners[size_t(b + r)];
        scene::pixel_ray(cam, float(s * (k % cw)), float(s * (k / cw)), &o[size_t(3 * r)], &d[size_t(3 * r)]);
        if (scene.effects.ndc) scene::to_ndc(cam, scene.ndc_near, &o[size_t(3 * r)], &d[size_t(3 * r)]);
      }
      const Shaded sh = shade_rays(o, d, R);
      const auto pc = sh.part.c.to_host(), pk = sh.part.kept_acc.to_host(), pa = sh.part.acc.to_host();
      const auto pd = sh.part.depth.to_host();
      std::copy(pc.begin(), pc.end(), cc.begin() + b * E);
      std::copy(pk.begin(), pk.end(), ck.begin() + b);
      std::copy(pa.begin(), pa.end(), ca.begin() + b);
      std::copy(pd.begin(), pd.end(), cd.begin() + b);
      if (region) std::copy(sh.inside.begin(), sh.inside.end(), ci.begin() + b);
    }
    for (int64_t b : which) {
      const size_t i = size_t(b);
      const int bx = int(b % w), by = int(b / w);
      for (int e = 0; e < E; ++e) c[i * E + size_t(e)] *= 4.0;
      kept_acc[i] *= 4.0;
      acc[i] *= 4.0;
      depth[i] *= 4.0;
      if (region) inside[i] *= 4.0;
      for (int dy = 0; dy <= 1; ++dy)
        for (int dx = 0; dx <= 1; ++dx) {
          const size_t q = size_t(corner_id[size_t(by + dy) * cw + size_t(bx + dx)]);
          for (int e = 0; e < E; ++e) c[i * E + size_t(e)] += cc[q * E + size_t(e)];
          kept_acc[i] += ck[q];
          acc[i] += ca[q];
          acc_lo[i] = std::min(acc_lo[i], ca[q]);
          acc_hi[i] = std::max(acc_hi[i], ca[q]);
          depth[i] += cd[q];
          if (region) inside[i] += ci[q];
        }
      rays_in[i] = 8.0;
    }
  };
  // Every block's centre first. Then the blocks whose centre differs from a neighbour's (blocks_to_refine)
  // get the other sub-rays: elsewhere the n x n average equals the centre up to the map's curvature. For
  // odd n the centre is the middle sub-ray and is kept (a merged block: the others form its group); for
  // even n it is not one of them and is replaced.
  add_rays(0.5f, 0.5f, {});
  if (supersample != 1) {
    std::vector<float> c0(c.begin(), c.end()), a0(acc.begin(), acc.end());
    const std::vector<uint8_t> refine = blocks_to_refine(c0, E, a0, w, h, refine_contrast);
    std::vector<int64_t> which;
    for (int64_t b = 0; b < n; ++b)
      if (refine[size_t(b)]) which.push_back(b);
    out.refined = int64_t(which.size());
    // Shading merged per depth slab where SICT on every sub-ray sample is what costs (many kept samples a
    // ray: soft forward-facing geometry); on crisp surfaces the merge saves nothing (docs/results.md).
    const double kept_per_ray = double(out.content.kept) / double(std::max<int64_t>(1, n));
    out.merged = !quincunx && !which.empty() && kept_per_ray >= double(merge_kept_per_ray);  // groups, not corners
    const bool keep_centre = quincunx || supersample % 2 == 1;
    if (!keep_centre)
      for (int64_t b : which) {
        std::fill(c.begin() + b * E, c.begin() + (b + 1) * E, 0.0);
        kept_acc[size_t(b)] = acc[size_t(b)] = depth[size_t(b)] = 0.0;
        acc_lo[size_t(b)] = 1.0f;
        acc_hi[size_t(b)] = 0.0f;
        if (region) inside[size_t(b)] = 0.0;
      }
    if (quincunx) {
      add_corners(which);
    } else if (out.merged) {
      add_groups(which, keep_centre);
    } else if (!which.empty()) {
      for (int sy = 0; sy < supersample; ++sy)
        for (int sx = 0; sx < supersample; ++sx) {
          if (keep_centre && sx == supersample / 2 && sy == supersample / 2) continue;  // rendered above
          add_rays((sx + 0.5f) / float(supersample), (sy + 0.5f) / float(supersample), which);
        }
    }
    if (!quincunx)
      for (int64_t b : which) rays_in[size_t(b)] = double(supersample) * supersample;
  }
  auto mean_of = [&](const std::vector<double>& sum, int per_block) {
    std::vector<float> m(sum.size());
    for (size_t i = 0; i < sum.size(); ++i) m[i] = float(sum[i] / rays_in[i / size_t(per_block)]);
    return m;
  };
  if (region) {
    out.region_mask.assign(static_cast<size_t>(n), 0.0f);
    for (int64_t r = 0; r < n; ++r) {
      const double k = kept_acc[size_t(r)] / rays_in[size_t(r)];  // mean kept weight; 1e-6 as for one ray
      out.region_mask[size_t(r)] = k > 1e-6 ? float(std::clamp(inside[size_t(r)] / kept_acc[size_t(r)], 0.0, 1.0)) : 0.0f;
    }
  }
  out.content.c = Tensor::from_host(mean_of(c, E), {n, E}, "camera content");
  out.content.kept_acc = Tensor::from_host(mean_of(kept_acc, 1), {n}, "camera kept opacity");
  out.content.acc = Tensor::from_host(mean_of(acc, 1), {n}, "camera opacity");
  out.content.depth = Tensor::from_host(mean_of(depth, 1), {n}, "camera depth");
  if (geo.has_background && stride() > 1)
    out.pixel_acc = pixel_opacity(scene, cam, w, h, acc_lo, acc_hi, std::max(chunk, 8192));
  return out;
}

std::vector<float> StyleModel::pixel_opacity(const scene::Scene& scene, const scene::Camera& cam, int w, int h,
                                             const std::vector<float>& acc_lo, const std::vector<float>& acc_hi,
                                             int chunk) const {
  // A block whose sub-rays, and its 8 neighbours' sub-rays, all saw (almost) nothing or (almost) full
  // opacity lies away from any silhouette: its pixels take that value. Only the other blocks' pixels are
  // rendered, one ray each, in calls bounded as render_camera's (rays_per_call).
  constexpr float kSettled = 1e-3f;
  const int s = stride(), W = cam.width, H = cam.height;
  auto block = [&](int bx, int by) { return size_t(std::clamp(by, 0, h - 1)) * w + size_t(std::clamp(bx, 0, w - 1)); };
  std::vector<float> out(size_t(W) * H, 0.0f);
  std::vector<int64_t> todo;  // pixel indices to render
  for (int by = 0; by < h; ++by)
    for (int bx = 0; bx < w; ++bx) {
      bool empty = true, full = true;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const size_t k = block(bx + dx, by + dy);
          empty = empty && acc_hi[k] < kSettled;
          full = full && acc_lo[k] > 1.0f - kSettled;
        }
      for (int y = by * s; y < std::min(H, (by + 1) * s); ++y)
        for (int x = bx * s; x < std::min(W, (bx + 1) * s); ++x) {
          if (empty || full)
            out[size_t(y) * W + x] = full ? 1.0f : 0.0f;
          else
            todo.push_back(int64_t(y) * W + x);
        }
    }
  if (todo.empty()) return out;
  const scene::Rays rays = scene::camera_rays(scene, cam);
  const OpacityHead head;
  const Geometry geo = inference_geometry();  // as render_camera_content's
  const size_t step = size_t(rays_per_call(geo, chunk));
  for (size_t b = 0; b < todo.size(); b += step) {
    const size_t R = std::min(todo.size() - b, step);
    std::vector<float> o(3 * R), d(3 * R);
    for (size_t i = 0; i < R; ++i)
      for (int k = 0; k < 3; ++k) {
        o[3 * i + k] = rays.origins[size_t(3 * todo[b + i] + k)];
        d[3 * i + k] = rays.directions[size_t(3 * todo[b + i] + k)];
      }
    const Tensor origins = Tensor::from_host(o, {int64_t(R), 3}, "pixel origins");
    const Tensor dirs = Tensor::from_host(d, {int64_t(R), 3}, "pixel directions");
    const auto a = render_rays(geo, head, origins, dirs, RayOptions{}, nullptr).acc.to_host();
    for (size_t i = 0; i < R; ++i) out[size_t(todo[b + i])] = a[i];
  }
  return out;
}

std::vector<float> StyleModel::crop_rgb(const Tensor& img, int cam_w, int cam_h) {
  const int H = int(img.dim(2)), W = int(img.dim(3));
  if (H < cam_h || W < cam_w)
    throw Error("style model: the decoder gave " + std::to_string(W) + "x" + std::to_string(H) + " pixels for a " +
                std::to_string(cam_w) + "x" + std::to_string(cam_h) + " view");
  const auto v = img.to_host();
  std::vector<float> rgb(size_t(3) * cam_w * cam_h);
  const size_t plane = size_t(H) * W;
  for (int y = 0; y < cam_h; ++y)
    for (int x = 0; x < cam_w; ++x)
      for (int ch = 0; ch < 3; ++ch) {
        const float p = v[ch * plane + size_t(y) * W + x];
        if (std::isnan(p)) throw Error("style model: the decoded image has NaN pixels");
        rgb[(size_t(y) * cam_w + x) * 3 + ch] = std::clamp(p, 0.0f, 1.0f);
      }
  return rgb;
}

std::vector<float> StyleModel::stylize_camera(const CameraContent& cc, const style::StyleCode& code, int cam_w,
                                              int cam_h) const {
  return crop_rgb(decode_styled(cc.content, code, cc.height, cc.width, nullptr), cam_w, cam_h);
}

std::vector<float> StyleModel::stylize_camera_regions(const CameraContent& cc, const style::StyleCode& inside,
                                                      const style::StyleCode& outside, int cam_w, int cam_h) const {
  const int64_t n = int64_t(cc.width) * cc.height;
  if (int64_t(cc.region_mask.size()) != n) throw Error("style model: this content was rendered without a region");
  if (map_decoder->renormalises_relu4()) {
    // This decoder re-normalises a whole map to one style's relu4_1 statistics, so two styles cannot share
    // a map: each is drawn over the whole view and the pictures are blended by the region mask, upsampled
    // from the blocks (a blend of pictures, not the paper's of DST outputs; the edge is a block soft).
    std::vector<float> rgb = stylize_camera(cc, inside, cam_w, cam_h);
    const std::vector<float> out = stylize_camera(cc, outside, cam_w, cam_h);
    const auto m = upsample_blocks(cc.region_mask, cc.width, cc.height, stride(), cam_w, cam_h);
    for (size_t i = 0; i < m.size(); ++i)
      for (int c = 0; c < 3; ++c) rgb[i * 3 + c] = m[i] * rgb[i * 3 + c] + (1 - m[i]) * out[i * 3 + c];
    return rgb;
  }
  const auto c = cc.content.c.to_host(), k = cc.content.kept_acc.to_host();
  const int E = style::Sict::kEmbed;
  std::vector<float> c_in(c.size()), c_out(c.size()), k_in(k.size()), k_out(k.size());
  for (int64_t r = 0; r < n; ++r) {
    const float m = cc.region_mask[size_t(r)];
    for (int e = 0; e < E; ++e) {
      c_in[size_t(r * E + e)] = m * c[size_t(r * E + e)];
      c_out[size_t(r * E + e)] = (1.0f - m) * c[size_t(r * E + e)];
    }
    k_in[size_t(r)] = m * k[size_t(r)];
    k_out[size_t(r)] = (1.0f - m) * k[size_t(r)];
  }
  Tensor y = dst.apply(Tensor::from_host(c_in, {n, E}, "content inside"), Tensor::from_host(k_in, {n}, "opacity inside"),
                       inside, nullptr);
  const Tensor y_out = dst.apply(Tensor::from_host(c_out, {n, E}, "content outside"),
                                 Tensor::from_host(k_out, {n}, "opacity outside"), outside, nullptr);
  nn::axpby(1.0f, y_out, 1.0f, y);
  return crop_rgb(decode_rows(std::move(y), cc.content.acc, cc.height, cc.width, nullptr, nullptr), cam_w, cam_h);
}

void StyleModel::over_background(std::vector<float>& rgb, const CameraContent& cc, int cam_w, int cam_h) const {
  if (!features.geo.has_background) return;
  if (rgb.size() != size_t(3) * cam_w * cam_h) throw Error("over_background: the image is not " + std::to_string(cam_w) + "x" + std::to_string(cam_h));
  const bool per_pixel = cc.pixel_acc.size() == size_t(cam_w) * cam_h;
  const std::vector<float> alpha =
      per_pixel ? cc.pixel_acc : upsample_blocks(cc.content.acc.to_host(), cc.width, cc.height, stride(), cam_w, cam_h);
  const auto& bg = features.geo.background;
  for (size_t i = 0; i < alpha.size(); ++i) {
    const float a = std::clamp(alpha[i], 0.0f, 1.0f);
    for (int c = 0; c < 3; ++c) rgb[i * 3 + c] = rgb[i * 3 + c] * a + bg[size_t(c)] * (1 - a);
  }
}

void StyleModel::collect_params(std::vector<nn::Param*>& out) {
  sict.collect_params(out);
  dst.collect_params(out);
  map_decoder->params_of(*this).collect_params(out);
}

void StyleModel::collect_buffers(std::vector<nn::StateBuffer*>& out) { sict.collect_buffers(out); }

void StyleModel::save(io::Checkpoint& ck) {
  features.save(ck);  // geometry, field, decoder ("model.*")
  sict.save(ck, "");
  dst.save(ck, "");
  map_decoder->save(*this, ck);
  ck.meta["style_model"] = {
      {"sict", style::sict_mode_name(sict.mode)},
      {"dst_bias", dst.bias},
      {"decoder", style_decoder_name(decoder_kind())},
      {"inference_supersample", inference_supersample == kQuincunx ? json(supersample_name(kQuincunx))
                                                                   : json(inference_supersample)},
      {"decoder_phases", decoder_phases}};
}

StyleModel StyleModel::load(const io::Checkpoint& ck) {
  if (!ck.meta.contains("style_model"))
    throw Error("checkpoint " + ck.path + " has no style model (kind '" + ck.kind +
                "'; train one with `stylerf train-style`)");
  style::SictMode mode;
  bool bias = true;
  StyleDecoderKind decoder = StyleDecoderKind::Stage2;
  int supersample = 1;
  bool phases = false;
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
  } catch (const json::exception& e) {
    throw Error("checkpoint " + ck.path + ": bad style-model metadata (" + e.what() + ")");
  } catch (const Error& e) {
    throw Error("checkpoint " + ck.path + ": " + e.what());
  }
  StyleModel m = create(FeatureModel::load(ck), mode, bias, 0, decoder);
  m.sict.load(ck, "");
  m.dst.load(ck, "");
  m.map_decoder->load(m, ck);
  if (!valid_supersample(supersample))
    throw Error("checkpoint " + ck.path + ": style_model.inference_supersample " + std::to_string(supersample) +
                " is outside 1.." + std::to_string(kMaxSupersample) + " (or quincunx)");
  m.inference_supersample = supersample;
  if (phases && !m.map_decoder->has_vgg_pool())
    throw Error("checkpoint " + ck.path + ": style_model.decoder_phases is set for the " +
                style_decoder_name(decoder) + " decoder (only the vgg-adain decoders have them)");
  m.decoder_phases = phases;
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
