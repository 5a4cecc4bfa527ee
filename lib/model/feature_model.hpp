// Stage 2's model: the frozen geometry of a density checkpoint, the feature field (VM grid of VGG relu3_1
// features + basis; lib/model/feature_field.hpp) and a decoder from rendered feature maps to RGB.
//
// Two decoder profiles, both real (docs/design.md, "Profiles"):
//   paper: features rendered at full resolution (one ray per pixel), then the PlainDecoder: eight
//          reflect-padded 3x3 convs 256-256-256-256-128-128-64-64-3, no upsampling (from scratch);
//   fast:  features rendered at relu3_1's own resolution (one ray per 4x4 block, through its centre),
//          then a decoder with two x2 upsamplings, initialised from AdaIN's pretrained decoder after its
//          relu4_1 stage and fine-tuned: 16x fewer rays and about 10x fewer decoder FLOPs per patch.
// The decoder outputs RGB in [0, 1] (clamped only when written as an image).
// Parameters: the field's ("feature_grid" group 0, "feature_basis" group 1) and the decoder's
// ("decoder.<index>.weight/bias", group 2).
#pragma once
#include <string>

#include "lib/io/checkpoint.hpp"
#include "lib/model/feature_field.hpp"
#include "lib/model/geometry.hpp"
#include "lib/nn/conv_stack.hpp"
#include "lib/scene/rays.hpp"
#include "lib/scene/scene.hpp"

namespace stylerf::model {

enum class DecoderProfile { Fast, Paper };
DecoderProfile parse_decoder_profile(const std::string& s);  // "fast" | "paper"
const char* decoder_profile_name(DecoderProfile p);
// Rays per stride x stride block of pixels: 4 (fast) or 1 (paper).
int render_stride(DecoderProfile p);

// Optimiser groups of the stage-2 parameters.
enum FeatureGroup { kGroupGrid = 0, kGroupBasis = 1, kGroupDecoder = 2 };

class FeatureModel : public nn::Module {
 public:
  Geometry geo;  // frozen
  FeatureField field;
  DecoderProfile profile = DecoderProfile::Fast;
  nn::ConvStack decoder;

  // field from `cfg` over `geo`, decoder by profile (fast: from AdaIN's decoder weights file, which must
  // be installed; paper: He init), seeded.
  static FeatureModel create(const Geometry& geo, const FeatureFieldConfig& cfg, DecoderProfile profile,
                             uint64_t seed);
  int stride() const { return render_stride(profile); }

  // A camera's feature map [1, C, h, w] with h = ceil(H/s), w = ceil(W/s) (s = stride), rendered in
  // chunks with no gradient, and the opacity and depth (divided by opacity) of the same rays [h][w].
  struct FeatureMap {
    int width = 0, height = 0;  // w, h
    Tensor features;            // [1, C, h, w]
    std::vector<float> acc, depth;
  };
  FeatureMap render_feature_map(const scene::Scene& scene, const scene::Camera& cam, int chunk = 4096) const;
  // A whole camera decoded to RGB: interleaved [H*W*3] in [0,1] (clamped), plus the feature map itself.
  struct DecodedView {
    int width = 0, height = 0;
    std::vector<float> rgb;  // [H][W][3]
    FeatureMap map;
  };
  DecodedView render_decoded(const scene::Scene& scene, const scene::Camera& cam, int chunk = 4096) const;

  void collect_params(std::vector<nn::Param*>& out) override;

  // Checkpoint kind "features": the geometry ("geometry.*"), the field and decoder ("model.*"), and
  // meta["feature_model"] (profile, field config, decoder architecture). A loaded model's decoder is frozen
  // (nn::ConvStack::freeze: inference reuses its Winograd filter transforms) until its params are taken.
  void save(io::Checkpoint& ck);
  static FeatureModel load(const io::Checkpoint& ck);
};

// Rays through the centres of the stride x stride blocks of `cam` (w = ceil(W/s), h = ceil(H/s) of them,
// row-major), in the scene's ray space; NDC uses the full camera, exactly as training rays do. (fx, fy) in
// [0, 1) moves every ray to that fraction of its block (0.5, 0.5: the centre; supersampling uses others).
scene::Rays block_rays(const scene::Scene& scene, const scene::Camera& cam, int stride, int& w, int& h,
                       float fx = 0.5f, float fy = 0.5f);

// The camera for a feature map rendered at 1/stride of its resolution: ceil(W/s) x ceil(H/s) pixels whose
// centres sit at the centres of the full-resolution s x s blocks (feature (j + 0.5) <-> pixel s (j + 0.5)).
scene::Camera strided_camera(const scene::Camera& cam, int stride);

}  // namespace stylerf::model
