// The decoders that draw stage 3's stylised maps, map [1, 256, h, w] -> RGB [1, 3, h s, w s] (StyleModel
// calls them through this interface; the kinds are described at StyleDecoderKind, lib/model/style_model.hpp).
//
// A MapDecoder is behaviour only: one stateless object per kind (map_decoder_for), the parameters staying
// in the StyleModel (stage 2's features.decoder; vgg_tail and style_decoder for the VGG-AdaIN kinds). So a
// StyleModel stays a plain value: copying or moving it needs no rebinding of its decoder.
#pragma once
#include <vector>

#include "lib/model/style_model.hpp"

namespace stylerf::model {

class MapDecoder {
 public:
  virtual ~MapDecoder() = default;
  virtual StyleDecoderKind kind() const = 0;
  // Whether it needs the fast profile (maps at relu3_1's own 1/4 resolution: the VGG tail's input).
  virtual bool needs_fast_profile() const = 0;
  // Whether it re-normalises relu4_1 to the style's statistics: the style code then carries them, and a
  // map can hold one style only (regions blend pictures, not DST outputs).
  virtual bool renormalises_relu4() const { return false; }
  // Whether it has VGG's 2x2 pool (the vgg-adain kinds): what StyleModel::decoder_phases applies to.
  virtual bool has_vgg_pool() const { return false; }
  // A fresh model's decoder: what it loads (VGG's tail, AdaIN's decoder) into m.
  virtual void init(StyleModel& m) const = 0;
  // code: the style's (relu4_1 statistics where renormalises_relu4); ctx: training (null at inference,
  // which also takes maps of odd sides).
  virtual Tensor forward(const StyleModel& m, const Tensor& map, const style::StyleCode* code,
                         StyleModel::DecoderCtx* ctx) const = 0;
  // drgb -> dmap (undefined without need_dx); accumulates the decoder's parameter gradients.
  virtual Tensor backward(StyleModel& m, const StyleModel::DecoderCtx& ctx, const Tensor& drgb, bool need_dx) const = 0;
  // VGG's relu4_1 of a map before any re-normalisation [1, 512, h', w'] (inference): the VGG-AdaIN kinds.
  virtual Tensor relu4(const StyleModel& m, const Tensor& map) const = 0;
  // The trained parameters and their checkpoint names (Stage2's are the feature model's, saved with it).
  virtual nn::Module& params_of(StyleModel& m) const = 0;
  virtual void save(StyleModel& m, io::Checkpoint& ck) const = 0;
  virtual void load(StyleModel& m, const io::Checkpoint& ck) const = 0;
};

}  // namespace stylerf::model
