// The style stage's 2D warm start reads a 256-channel map per training view at relu3_1's resolution (one
// pixel per 4x4 block, the fast profile's rays). Two sources:
//  - vgg: stage 2's cached relu3_1 targets, VGG of the photographs (the trainer's default; free when the
//    feature stage left its cache);
//  - rendered: stage 2's feature field rendered at the block centres of every training view, i.e. what the
//    rendered steps and inference feed the stylizer. The field's maps are blurrier and of lower contrast
//    than VGG's, so a warm start on VGG maps learns a stylizer for inputs it never meets again (measured:
//    docs/experiments.md, the warm-maps row).
// Rendered maps hold a ray's mean feature (the composite over its samples divided by its opacity, the
// background removed) and, beside it, the opacity: a warm step then forms c = acc * SICT(mean), the 2D
// stand-in for the sum over kept samples of w_i SICT(f_i) that a rendered step computes.
#pragma once
#include <iosfwd>
#include <string>
#include <vector>

#include "lib/features/feature_targets.hpp"
#include "lib/model/feature_model.hpp"
#include "lib/scene/scene.hpp"

namespace stylerf::train {

enum class WarmMaps { Vgg, Rendered };
const char* warm_maps_name(WarmMaps m);
WarmMaps parse_warm_maps(const std::string& name);  // "vgg" | "rendered"; anything else throws, naming it

// Below this opacity a ray's mean feature is taken as 0 (nothing there to normalise; its c is scaled by
// the opacity anyway).
constexpr float kWarmMapMinOpacity = 1e-4f;

struct RenderedWarmMaps {
  features::FeatureTargets maps;  // [V, Hf, Wf, 256] channels innermost, the layout gather_targets reads
  std::vector<float> acc;         // [V][Hf][Wf]
  float opacity(int view, int i, int j) const;  // map pixel (row i, column j) of a view, clamped at the borders
};

// Every training view of `scene` through the (fast-profile) feature model; a progress line per view on `log`.
RenderedWarmMaps render_warm_maps(const model::FeatureModel& features, const scene::Scene& scene, std::ostream* log);

}  // namespace stylerf::train
