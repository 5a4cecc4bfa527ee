#include "lib/train/recipes.hpp"

#include "host/error.hpp"

namespace stylerf::train {

Recipe parse_recipe(const std::string& name) {
  if (name == "fast") return Recipe::Fast;
  if (name == "paper") return Recipe::Paper;
  throw host::Error("recipe '" + name + "' is not one of: fast, paper");
}

const char* recipe_name(Recipe r) { return r == Recipe::Fast ? "fast" : "paper"; }

Recipe style_recipe_for(const model::FeatureModel& fm, const std::string& recipe, const std::string& features_path) {
  const std::string profile = model::decoder_profile_name(fm.profile);
  const Recipe r = parse_recipe(recipe.empty() ? profile : recipe);
  if (r == Recipe::Fast && fm.profile != model::DecoderProfile::Fast)
    throw host::SettingError("recipe", "fast needs a fast-profile feature checkpoint; " + features_path + " has the " +
                                           profile + " profile (the paper recipe takes it)");
  return r;
}

StyleTrainConfig style_recipe(Recipe r) {
  StyleTrainConfig c;
  if (r == Recipe::Paper) return c;
  // The decoder: VGG's relu3_1 -> relu4_1 tail, relu4_1 moved to the style's relu4_1 statistics (from
  // the scene's at inference: model::SceneStyleStats), then AdaIN's pretrained decoder (vgg-adain-relu4),
  // with the pool at its four grid phases (below). Measured against vgg-adain (docs/experiments.md,
  // "vgg-adain-relu4 with the grid phases"): horns 1/8, a scene no recipe was tuned on, 31.4 min of style
  // training on one feature checkpoint: held-out style loss 1.94x -> 1.18x 2D AdaIN's (worst style 4.26x
  // -> 1.66x), content 1.55x -> 1.44x, short-range RMSE 0.88x -> 0.89x per-frame AdaIN's and LPIPS 0.83x
  // -> 0.89x (vgg-adain trained without the phases, decoded with them); lego 1/4, both with the phases,
  // relu4 in 30 min against vgg-adain's 45: style 0.62x vs 0.71x, short RMSE 0.66x vs 0.61x, LPIPS 0.55x
  // vs 0.66x; fern 1/8 (neither with the phases) 0.99-1.10x against 1.44-1.70x.
  c.style_decoder = model::StyleDecoderKind::VggAdainRelu4;
  c.warm_start = 1600;
  // ...or 65% of a --minutes budget if that comes first. Fern 1/8, 26 minutes on the fern90 features: all
  // 1430 steps 2D (the count never ended) 1.517x 2D AdaIN's style loss; 860 2D steps (71% of the minutes)
  // then 204 rendered 1.372x, held-out patch style loss 17.6 -> 15.2. Fern's best 45-minute runs spent
  // ~65% of 45 minutes on the warm start (1600 2D then ~340 rendered); lego's 30 minutes ~67%.
  c.warm_share = 0.65f;
  c.warm_maps = WarmMaps::Rendered;
  c.lr_stylizer = 1e-3f;
  c.lr_decoder = 1e-5f;
  c.lr_decay_ratio = 0.1f;
  c.style_size = 256;
  // Content x3 against style x20 (the paper's 1 : 20): the stylizer keeps more of the scene and, on test
  // views, matches the style better too (docs/experiments.md, "The content weight"). Horns 1/8 (a scene no
  // recipe was tuned on), one feature checkpoint, 300 2D steps each, 12 held-out styles x 5 test views:
  // weight 1 / 3 / 10 gave style loss 1.646x / 1.507x / 1.742x 2D AdaIN's, content 1.588x / 1.381x /
  // 1.177x; short-range RMSE 0.942x -> 0.828x per-frame AdaIN's at 3. The demo's scene, one feature
  // checkpoint, 100 steps: weight 1 / 3 gave style 1.085x / 0.912x, content 1.172x / 1.087x.
  c.weights.content = 3.0f;
  // Inference rays in the blocks at edges, by the scene (model::default_inference_supersample): the quincunx
  // (the centre and the four shared corner rays) on forward-facing scenes at 800 px and more, where it was
  // the more consistent for a third of the content render (fern 1008x756: a frame 9.3 vs 22.7 s); 3 x 3
  // elsewhere, where the nine were (lego 800x800, the demo's 128 px scene; docs/results.md).
  c.inference_supersample = model::kSupersampleByScene;
  // VGG's pool at all four grid offsets: the decoder paints from relu4_1 at every map pixel, not on a
  // 2-pixel grid fixed to the image. Lego 1/4 with vgg-adain (the 60-minute run's model, 3 held-out
  // styles, eval table): short-range RMSE 0.839x -> 0.656x per-frame AdaIN's, LPIPS 0.740x -> 0.563x,
  // held-out style loss 0.620x -> 0.665x, with a decoder trained without them (docs/experiments.md).
  c.decoder_phases = true;
  // The content skip beside DST (lib/style/content_skip.hpp): the object's parts stay under the style. Lego
  // 800x800, one feature checkpoint, 12 minutes of style training each, 6 held-out styles x 2 test views
  // (docs/experiments.md, "The content skip"): style / content / LPIPS-to-the-truth ratios to 2D AdaIN
  // 0.538x / 1.573x / 1.468x without it, 0.397x / 1.250x / 1.205x with it; a step costs 5-10% more.
  c.content_skip = true;
  return c;
}

}  // namespace stylerf::train
