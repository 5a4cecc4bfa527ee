// Stage 3's model: stage 2's feature model (frozen geometry and feature field; its decoder fine-tuned) and
// the stylizer (lib/style: SICT per kept sample, DST on the rendered map). One styled render:
//   rays -> march/density/weights/keep (frozen) -> per kept sample: grid components -> basis (256) ->
//   SICT (32) -> weighted sum over kept samples -> c [R, 32] and kept opacity w_r ->
//   DST(c, w_r; the style's code) [R, 256] (+ (1 - acc) x the stage-2 background feature, unstyled) ->
//   map [1, 256, h, w] -> decoder -> RGB.
// The content part (up to c and w_r) does not depend on the style: render it once and apply any number of
// styles (zero-shot use, interpolation), which is what render_content / decode_styled split.
//
// Parameters: "style.sict.*" and "style.dst.*" (group kGroupStylizer), the decoder's (group
// kGroupStyleDecoder): stage 2's "decoder.*", or with the VGG-AdaIN style decoder "style.decoder.*"; the
// field's parameters are not listed (frozen).
#pragma once
#include <algorithm>
#include <atomic>
#include <stdexcept>
#include <string>

#include "lib/io/checkpoint.hpp"
#include "lib/model/block_refine.hpp"
#include "lib/model/feature_model.hpp"
#include "lib/model/region.hpp"
#include "lib/nn/vgg.hpp"
#include "lib/nn/vgg_tail.hpp"
#include "lib/style/content_skip.hpp"
#include "lib/style/dst.hpp"
#include "lib/style/sict.hpp"

namespace stylerf::model {

enum StyleGroup { kGroupStylizer = 0, kGroupStyleDecoder = 1 };
constexpr float kStyleWeightThreshold = 1e-3f;  // samples below this weight never reach SICT
constexpr int kMaxSupersample = 8;  // inference rays per block and axis (render_camera_content)
// The content rays of a block at inference ("supersample"): n >= 1, n x n rays spread evenly over the block
// (1: its centre); or kQuincunx, the centre ray (weight 4) and the rays through the block's four corners
// (weight 1 each), the corners shared with the neighbouring blocks: about one ray more a block where
// 3 x 3 takes eight more (docs/results.md, "Quincunx rays a block").
constexpr int kQuincunx = -1;
inline bool valid_supersample(int n) { return n == kQuincunx || (n >= 1 && n <= kMaxSupersample); }
// "quincunx", or n x n as "3x3" ("1" for the centre ray).
std::string supersample_name(int n);
// "quincunx" or "q" -> kQuincunx, "1".."8" or supersample_name's "3x3" -> n; anything else is an error naming
// the value and the choices.
int parse_supersample(const std::string& text);
// A recipe's inference_supersample that the style trainer settles by the scene (default_inference_supersample).
constexpr int kSupersampleByScene = 0;
// The map side (blocks) from which forward-facing (NDC) scenes take the quincunx.
constexpr int kQuincunxMapSide = 200;
// The quincunx for forward-facing (NDC) scenes whose feature map has at least kQuincunxMapSide blocks on its
// longer side (images of 800 px and more at the fast profile's stride 4); 3 x 3 elsewhere. Measured
// (docs/results.md, "Quincunx rays a block"): fern 1008x756 is more consistent with it (short-range RMSE
// 0.735x per-frame AdaIN's against 0.753x) for a third of the content render; lego 800x800 (an object on
// crisp surfaces) less (0.717x against 0.694x, LPIPS 0.755x against 0.698x), as the demo's 128 px scene
// (0.842x against 0.746x). Fern and horns at 1/8 are not measured with it: 3 x 3, as they were.
int default_inference_supersample(int map_w, int map_h, bool ndc);
// render_camera_content shades a refined block's sub-rays merged per depth slab (render_ray_groups) when
// the centre rays keep at least this many samples a ray on average: fern 1/8 keeps ~180 (content 2.05x
// faster with kMergeSteps, the same style loss and consistency), lego ~6 (the merge costs more than it
// saves).
constexpr float kMergeKeptPerRay = 16.0f;
// ... and merges the samples of kMergeSteps march steps (a slab of 2 voxels at TensoRF's half-voxel step)
// into one shade: fern 1/8's content a view 7.5 s at 1 step, 6.2 at 2, 5.6 at 4, 5.6 at 8; frames 0.13,
// 0.34, 1.09 of 255 from 1 step's (docs/results.md).
constexpr int kMergeSteps = 4;

// The decoder that draws stylised maps (train-style --style-decoder):
//  - Stage2 ("stage2"): stage 2's decoder, fine-tuned: the paper's. It has seen one scene's photographs,
//    so it must learn to draw painted texture within the style stage.
//  - VggAdain ("vgg-adain"): VGG's frozen relu3_1 -> relu4_1 (nn::VggTail), then AdaIN's pretrained
//    decoder (fine-tuned at the decoder's rate). It was trained to draw images whose VGG statistics match
//    stylised relu4_1 features. Fast profile only: the map must be at relu3_1's own 1/4 resolution.
//  - VggAdainRelu4 ("vgg-adain-relu4"): VggAdain with the tail's relu4_1 output re-normalised to the style
//    image's own relu4_1 channel statistics (AdaIN at relu4_1, over each decoded map) before AdaIN's
//    decoder, which was trained on exactly such inputs. DST only sets relu3_1's statistics, from which the
//    tail's relu4_1 ones do not follow. In training the statistics re-normalised from are each patch's
//    own; at inference, a code with scene statistics (model::SceneStyleStats) is re-normalised from
//    those, the same for every frame, and one without from each frame's own (which flickers).
enum class StyleDecoderKind { Stage2, VggAdain, VggAdainRelu4 };
StyleDecoderKind parse_style_decoder(const std::string& s);  // an Error names the accepted values
const char* style_decoder_name(StyleDecoderKind k);
class MapDecoder;  // lib/model/map_decoder.hpp: what each kind does

// Thrown by render_camera_content between renderer calls once its cancel flag is set (an interactive viewer
// whose camera moved on): nothing of the render is kept.
struct RenderCancelled : std::runtime_error {
  RenderCancelled() : std::runtime_error("render cancelled") {}
};
const MapDecoder& map_decoder_for(StyleDecoderKind kind);

// The ray pipeline's value head of stage 3: the feature field's 256 channels per kept sample, then SICT. With
// the content skip its value is [SICT's 32 | the F grid components], so that one composite gives both.
class SictHead : public SampleHead {
 public:
  SictHead(const FeatureField& field, style::Sict& sict, bool training, bool with_components = false)
      : field_(field), sict_(sict), training_(training), with_components_(with_components) {}
  int channels() const override;
  Tensor forward(const Tensor& pos, const Tensor& dirs, std::unique_ptr<Context>* ctx) const override;
  // Accumulates into SICT's parameters (the field is frozen: no gradient flows further).
  void backward(const Context& ctx, const Tensor& dvalues) override;
  void collect_params(std::vector<nn::Param*>& out) override { sict_.collect_params(out); }
  // The batch statistics of the last training forward's context, for Sict::update_running.
  struct SictContext : Context {
    style::Sict::Context sict;
  };

 private:
  const FeatureField& field_;
  style::Sict& sict_;
  bool training_;
  bool with_components_;
};

class StyleModel : public nn::Module {
 public:
  FeatureModel features;  // geometry and field frozen; with the Stage2 decoder, its decoder is fine-tuned
  style::Sict sict;
  style::Dst dst;
  // The content skip (lib/style/content_skip.hpp): the composited features, channel by channel, beside DST's
  // path through the 32-channel embedding. Saved in the checkpoint; off in the paper's model.
  bool content_skip = false;
  style::ContentSkip skip;
  const MapDecoder* map_decoder = &map_decoder_for(StyleDecoderKind::Stage2);  // chosen by create()
  // Content rays per feature-map block that inference uses unless told otherwise (a recipe's choice, saved
  // in the checkpoint): n x n a block, or kQuincunx; 1: one ray per block centre, what training renders.
  int inference_supersample = 1;
  // Samples per voxel side of render_camera_content's march (every inference frame, the table's content,
  // the scene statistics); training keeps the geometry's own (0.5, TensoRF's). Set by create() from the
  // geometry (default_inference_step_ratio), not saved.
  float inference_step_ratio = 0.5f;
  // NDC scenes: a sample every voxel side (1.0) instead of every half: fern 1008x756's content 0.57x the
  // time, its decoded views and consistency unchanged (docs/results.md, "A sample a voxel at inference").
  // Other scenes keep their trained step (0.5): crisp surfaces, early termination already ends their rays.
  static float default_inference_step_ratio(const Geometry& g) {
    return g.ndc ? std::max(1.0f, g.step_ratio) : g.step_ratio;
  }
  // The geometry inference marches: the trained one at inference_step_ratio (grids and mask shared).
  Geometry inference_geometry() const { return features.geo.with_step_ratio(inference_step_ratio); }
  // Inference only (stylised_rows): how much of the stylised features a frame draws, AdaIN's alpha at
  // relu3_1. Each ray's y = s (DST + skip) + (1 - s) Z B, Z B its composited features themselves (the content
  // skip's components through the field's basis), before the background and the decoder, whose relu4_1 is
  // still moved to the style's statistics: at 0 a frame is 2D AdaIN at relu4_1 of the scene's own features.
  // Training is always at 1. Below 1 it needs the content skip (the components). Saved in the checkpoint; 1
  // unless set (--strength): below 1 won on lego and lost on horns and the milk carton (docs/experiments.md).
  float strength = 1.0f;
  void set_strength(float s);  // an Error unless s is in [0, 1], and below 1 without the content skip
  // VggAdain only: the tail's pool at all four of its grid offsets, interleaved by AdaIN's decoder where it
  // would repeat one (nn::maxpool2x2_phases_forward). Its picture moves with the map by one map pixel; a
  // single offset paints from relu4_1 on a grid of two map pixels fixed to the image, which shows as a
  // lattice of strokes that changes as the camera moves (docs/experiments.md). Saved in the checkpoint.
  bool decoder_phases = false;
  nn::VggTail vgg_tail;         // VggAdain*: frozen
  nn::ConvStack style_decoder;  // VggAdain*: AdaIN's decoder, "style.decoder.*"

  // A fresh stylizer over a trained feature model (seeded); the decoder's parameters go to group
  // kGroupStyleDecoder. VggAdain* load VGG and AdaIN's decoder from the weights folder.
  static StyleModel create(FeatureModel features, style::SictMode sict_mode, bool dst_bias, uint64_t seed,
                           StyleDecoderKind decoder = StyleDecoderKind::Stage2, bool content_skip = false);
  // The columns of a ray's content c: SICT's 32, and with the content skip the field's F components after them.
  int content_channels() const;

  // The stylised-map decoder, whichever kind: map [1, 256, h, w] -> RGB [1, 3, h s, w s]. Inference
  // (ctx null) takes odd sides too (VggAdain* pad the map's last row / column, and the image comes out
  // up to s pixels larger: crop_rgb cuts it); training needs even sides with VggAdain*.
  struct DecoderCtx {
    nn::VggTail::Ctx tail;
    nn::ConvStack::Ctx stack;
    Tensor relu4;  // VggAdainRelu4: the tail's output before the re-normalisation
    nn::ChannelStats relu4_target;
  };
  // code: the style's, for VggAdainRelu4 (its relu4_1 statistics); the others ignore it (may be null).
  Tensor decode_map(const Tensor& map, const style::StyleCode* code, DecoderCtx* ctx) const;
  // drgb -> dmap (undefined when need_dx is false); accumulates the decoder's parameter gradients.
  Tensor decode_map_backward(const DecoderCtx& ctx, const Tensor& drgb, bool need_dx);
  // A style image's code from its VGG taps: DST's (relu3_1), and for VggAdainRelu4 relu4_1's statistics
  // (taps to depth 4). ctx: DST's style-branch context, for training.
  style::StyleCode style_code(const nn::VggFeatures& taps, style::Dst::StyleContext* ctx) const;
  std::vector<nn::Param*> decoder_params();
  int stride() const { return features.stride(); }
  StyleDecoderKind decoder_kind() const;

  // The style-independent part of a render: c [R, content_channels()], the kept opacity w_r and the full
  // opacity [R].
  struct Content {
    Tensor c, kept_acc, acc;
    Tensor depth;  // [R] sum w t over all samples (not divided by acc)
    // Scenes with a background shell: what empty space adds to each row, (1 - acc) x stage 2's shell
    // features (unstyled, as the background feature of scenes with a colour); undefined otherwise.
    Tensor background;
    int64_t samples = 0, kept = 0;
  };
  struct Context {
    RayContext rays;
    std::unique_ptr<SictHead> head;  // bound to this model's sict; backward needs the same head
    style::Dst::ApplyContext dst;
    style::ContentSkip::Context skip;
    DecoderCtx decoder;
    int h = 0, w = 0;
  };
  // origins/dirs [R, 3] with R = h * w rays (row-major block centres at the profile's stride). training:
  // SICT uses batch statistics and ctx must be given.
  Content render_content(const Tensor& origins, const Tensor& dirs, bool training, uint32_t jitter_seed,
                         Context* ctx) const;
  // The style transformation of content rows c [R, content_channels()] with their kept opacity [R]: DST of the
  // SICT columns, plus the content skip of the component columns (SICT's running statistics). [R, 256].
  Tensor transform(const Tensor& c, const Tensor& kept_acc, const style::StyleCode& code, Context* ctx) const;
  // Inference's rows: transform() blended at the model's strength with each ray's own composited features,
  // s y + (1 - s) Z B (the component columns through the field's basis). What every stylised frame decodes.
  Tensor stylised_rows(const Tensor& c, const Tensor& kept_acc, const style::StyleCode& code) const;
  // The same blend for 2D feature rows: y = s y + (1 - s) z, z [R, 256] the features themselves.
  void blend_at_strength(Tensor& y, const Tensor& z) const;
  // The same for 2D feature rows (VGG maps, rendered mean-feature maps): c [R, 32] SICT's output, z [R, 256]
  // the features times their opacity and mean / var the statistics SICT normalised them with (the content
  // skip's input with the identity basis; ignored without the skip).
  Tensor transform_features(const Tensor& c, const Tensor& z, const Tensor& acc, const Tensor& mean,
                            const Tensor& var, const style::StyleCode& code, Context* ctx) const;
  // dy [R, 256] -> the gradients of DST's apply (dc: SICT's 32 columns) with the skip's d std added;
  // accumulates into unzip and the skip's gain.
  style::Dst::ApplyGrads transform_backward(Context& ctx, const Tensor& dy);
  // DST with a style's code, the background feature, the decoder: RGB [1, 3, h s, w s]. Without a context
  // (inference, held-out scores) at the model's strength (stylised_rows); with one, the trained transform.
  Tensor decode_styled(const Content& content, const style::StyleCode& code, int h, int w, Context* ctx) const;
  // VGG's relu4_1 of the styled map, what the vgg-adain decoders' tail gives before any re-normalisation
  // [1, 512, h', w'] (inference; VggAdain kinds only): what SceneStyleStats pools.
  Tensor relu4_of(const Content& content, const style::StyleCode& code, int h, int w) const;
  // The same from DST's output rows y [h w, 256] (consumed) and the full opacity acc [h w].
  // background: the rows' shell term (Content::background), added where the geometry has a shell.
  Tensor decode_rows(Tensor y, const Tensor& acc, int h, int w, const style::StyleCode* code, Context* ctx,
                     const Tensor& background = Tensor()) const;
  // drgb [1, 3, H, W]: accumulates into the decoder, DST and SICT; returns the code's gradients (dT, dmean,
  // dstd) for the style branch (Dst::style_code_backward).
  style::Dst::ApplyGrads backward(Context& ctx, const Tensor& drgb);

  // The deferred-vs-per-point proof's other side: DST applied to every kept sample's SICT output (weight
  // 1 each: unzip(T c_i) * std + mean), then the 256 channels composited. Inference only; equals
  // dst.apply(render_content(...).c, kept_acc) up to rounding, at (kept samples per ray) x the memory.
  RayResult render_styled_per_point(const Tensor& origins, const Tensor& dirs, const style::StyleCode& code) const;

  // Inference over a whole camera: content in chunks of rays (SICT with running statistics, so chunking
  // changes nothing), one DST and decoder pass over the map.
  struct CameraContent {
    int width = 0, height = 0;  // the map's (ceil(W/s), ceil(H/s))
    Content content;
    // With a region: per ray the fraction of its kept weight inside the region (the region's indicator
    // composited with the scene's weights, divided by the kept opacity; 0 where nothing was kept).
    std::vector<float> region_mask;
    // Scenes with a background, when the map is coarser than the image (stride > 1): the opacity of one
    // ray per image pixel [cam H * cam W] (the geometry alone, with early termination), so that
    // over_background cuts silhouettes at the image's resolution rather than the map's blocks. Rendered
    // only in blocks near a silhouette (pixel_opacity): elsewhere 0 or 1.
    std::vector<float> pixel_acc;
    // Blocks given their n x n sub-rays or their quincunx (supersample != 1; the others kept their centre ray).
    int64_t refined = 0;
    // Whether those blocks were shaded merged per depth slab (merge_kept_per_ray).
    bool merged = false;
    // Whether the centre rays after the first renderer call were shaded once per depth slab of their own
    // samples (merge_kept_per_ray, judged on that first call).
    bool slab_shaded = false;
  };
  // region: also renders its mask (a second pass over the same rays, with the indicator as the value).
  // supersample n > 1: n x n rays per block, spread evenly over it, and their content averaged (c, w_r,
  // acc, depth; the region mask as inside weight over kept weight of the block). Training renders one ray
  // per block centre, a point sample of the map; the average is its area integral, which moves smoothly as
  // the camera moves (fine geometry such as fern's leaves otherwise flickers in and out of the block
  // centres). DST is affine in (c, w_r) and SICT runs per point, so averaging content is averaging what
  // each sub-ray's map would have been before the decoder. Costs up to n^2 x the content render; matters
  // for the fast profile, whose one ray per block stands for 16 pixels (docs/results.md: what n = 2 buys on the
  // consistency table and costs a frame).
  // supersample kQuincunx: a refined block is (4 x its centre + its four corner rays) / 8, the same sums
  // weighted; each corner ray rendered once for all the refined blocks it touches, as the centre rays are
  // (one ray, shaded per depth slab when they are). A tent-like filter over the block and its neighbours'
  // edges for about one extra ray a block.
  // refine_contrast: only the blocks whose centre ray differs from a neighbour's by more than this get the
  // n x n sub-rays (or the quincunx); the others keep their centre (block_refine.hpp; 0: every block, the exact average).
  // merge_kept_per_ray: when the centre rays keep at least this many samples a ray on average, a refined
  // block's sub-rays other than the centre ray already rendered are one group (render_ray_groups): opacity,
  // depth and kept opacity exactly as above, SICT once per depth slab of kMergeSteps march steps on the
  // sub-rays' weight-averaged field components there instead of on every sub-ray sample (an approximation
  // of the average: exact where the features agree across the slab). The centre rays likewise: when the
  // first renderer call's rays keep at least this many samples a ray, the later calls shade each ray once
  // per depth slab of its own samples (fern: SICT on every kept sample was most of a centre ray's cost).
  // 0: always; infinity: never (the exact average, every sample shaded).
  // cancel: when given and set (from another thread), the render stops before its next renderer call by
  // throwing RenderCancelled.
  CameraContent render_camera_content(const scene::Scene& scene, const scene::Camera& cam, int chunk = 4096,
                                      const RegionHead* region = nullptr, int supersample = 1,
                                      float refine_contrast = kRefineContrast,
                                      float merge_kept_per_ray = kMergeKeptPerRay,
                                      const std::atomic<bool>* cancel = nullptr) const;
  // CameraContent::pixel_acc for a map of w x h blocks whose sub-rays' opacity ranged over
  // [acc_lo, acc_hi] per block: rendered one ray a pixel only near silhouettes (see the definition).
  std::vector<float> pixel_opacity(const scene::Scene& scene, const scene::Camera& cam, int w, int h,
                                   const std::vector<float>& acc_lo, const std::vector<float>& acc_hi, int chunk) const;
  // RGB interleaved [H*W*3] in [0,1] (clamped) of a camera's content under a style code, cut to the
  // camera's size.
  std::vector<float> stylize_camera(const CameraContent& cc, const style::StyleCode& code, int cam_w, int cam_h) const;
  // Compositional transfer (the paper's): the DST outputs of two styles blended on the feature map by the
  // region mask m, m yA + (1 - m) yB, then decoded. Since DST is linear in (c, w_r) this is computed as
  // DST_A(m c, m w_r) + DST_B((1 - m) c, (1 - m) w_r): two applies, no extra map-sized kernel. The
  // vgg-adain-relu4 decoder re-normalises a map to one style, so there the two stylised pictures are
  // blended by the mask instead.
  std::vector<float> stylize_camera_regions(const CameraContent& cc, const style::StyleCode& inside,
                                            const style::StyleCode& outside, int cam_w, int cam_h) const;

  // Scenes with a background colour: rgb (interleaved, cam_w x cam_h) composited over it by the rendered
  // opacity a (cc.pixel_acc, one ray per pixel, when it was rendered; else bilinear from the block
  // centres): rgb a + bg (1 - a). The decoder draws empty space
  // from stage 2's background feature, but stage 3's masked losses never look there, so its colour drifts
  // while the style is trained; this puts the scene's own background back. No-op without a background.
  void over_background(std::vector<float>& rgb, const CameraContent& cc, int cam_w, int cam_h) const;
  void collect_params(std::vector<nn::Param*>& out) override;
  // The full-resolution camera's inference outputs: decoder RGB [1, 3, H', W'] cut and clamped.
  static std::vector<float> crop_rgb(const Tensor& img, int cam_w, int cam_h);
  void collect_buffers(std::vector<nn::StateBuffer*>& out) override;

  // Checkpoint kind "style": the feature model's tensors and meta, the stylizer under "style.*", and
  // meta["style_model"] (SICT mode, DST bias). A loaded model's decoders are frozen (nn::ConvStack::freeze:
  // inference reuses their Winograd filter transforms) until their params are taken (an optimiser).
  void save(io::Checkpoint& ck);
  static StyleModel load(const io::Checkpoint& ck);
};

// A style image's relu3_1 features as rows [h*w, 256] for Dst::style_code, from VGG taps.
Tensor style_rows(const nn::VggFeatures& taps);

}  // namespace stylerf::model
