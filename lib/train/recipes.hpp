// Recipes: the named sets of settings a user picks instead of a dozen flags (`--recipe` on `stylerf run`
// and on each stage's command; a flag given as well overrides the recipe's value).
//   fast  the best measured on a CPU (docs/results.md): the fast feature profile (features at 1/4
//         resolution, an upsampling decoder, its patch loss the pixel MSE alone) and the style stage's
//         measured best settings;
//   paper the paper's settings exactly: full-resolution features and the PlainDecoder, stage 2's decoder
//         fine-tuned in stage 3, no warm start, the paper's learning rates.
#pragma once
#include <string>

#include "lib/train/style_trainer.hpp"

namespace stylerf::train {

enum class Recipe { Fast, Paper };

// "fast" | "paper"; anything else is an error naming the value and the choices.
Recipe parse_recipe(const std::string& name);
const char* recipe_name(Recipe r);

// Stage 3's settings. Fast (fast profile only): the vgg-adain decoder (VGG's tail, AdaIN's decoder), 1600 2D warm-start steps on
// rendered maps (or 65% of a --minutes budget if sooner), the stylizer at 1e-3 and the decoder at 1e-5 decaying to 0.1x, style images at 256 (the
// scale inference reads them), and inference at 3 x 3 rays per feature block. Paper: StyleTrainConfig's
// defaults, which are the paper's.
StyleTrainConfig style_recipe(Recipe r);
// The recipe a style stage over feature model `fm` (read from `features_path`, named in errors) runs:
// `recipe` ("fast" | "paper"), or when empty the one named like the model's profile. The fast recipe
// needs a fast-profile model (its decoder reads relu3_1-sized maps).
Recipe style_recipe_for(const model::FeatureModel& fm, const std::string& recipe, const std::string& features_path);

}  // namespace stylerf::train
