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

}  // namespace stylerf::demo
