// Images stylerf makes by itself, so the demo and tests need no downloaded data:
// a ray-traced content image (shapes on a checker floor) and a painterly style image.
#pragma once
#include <vector>

namespace stylerf::demo {

// Planar RGB, [3, H, W], values in [0, 1].
struct RgbImage {
  int width = 0, height = 0;
  std::vector<float> data;
};

// A small analytic scene (sphere, box, cylinder on a checker floor, sky gradient) seen from a camera
// at the given azimuth, with Lambert shading and hard shadows.
RgbImage render_content_image(int width, int height, float azimuth_degrees = 30.0f);

// Domain-warped swirls through a saturated palette with directional brush streaks: strong colour and
// texture statistics, so a style transfer result is easy to judge by eye.
RgbImage make_style_image(int width, int height, int variant = 0);

// A family of style images that differ in both palette and texture, so that a style stage trained on some
// of them has to read colour and texture from the image (the variants of make_style_image share two
// palettes and one texture: a model that ignored its style input fitted them all alike). Each variant
// draws, from a hash of `variant`: a 3- or 4-colour palette (a random base hue, in an analogous,
// complementary or triadic scheme), one of seven textures (swirled brush streaks, wavy stripes, dots,
// stained-glass cells, cross-hatching, ripples, a noisy mosaic) and its scale and angle. Deterministic.
RgbImage make_varied_style_image(int width, int height, int variant);

}  // namespace stylerf::demo
