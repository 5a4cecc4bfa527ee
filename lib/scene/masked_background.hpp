// Object captures shot or cut out on a plain background (a product photo on white, a capture whose
// background was masked away) need a background colour: the rays that leave the object's box see it, and
// without one the density stage can only paint it onto the box's walls (milk_carton at 1/4 stalled at
// 10 dB). Their JPEGs carry no alpha, so the colour is read off the images' borders: on when nearly all
// border pixels of the training views share one colour. Real backgrounds (cup, bird_figurine, beer_can)
// share it in 15-82% of their border pixels, the masked milk_carton in 100%.
#pragma once
#include <array>
#include <cstdint>
#include <vector>

#include "lib/scene/scene.hpp"

namespace stylerf::scene {

inline constexpr float kBorderTolerance = 0.06f;  // largest channel difference still "the same colour"
inline constexpr double kUniformBorderShare = 0.95;

struct BorderColour {
  std::array<float, 3> rgb{0, 0, 0};  // the per-channel median of the border pixels
  double share = 0;                   // the fraction of border pixels within the tolerance of rgb
  long pixels = 0;                    // border pixels looked at
};

// The border ring of each view (max(1, min(width, height) / 50) pixels wide), pooled over the views.
BorderColour border_colour(const std::vector<View>& views, float tolerance = kBorderTolerance);

// For an object-centric scene whose images had no alpha: switches the background colour on (with a note
// saying why) when the training views' borders are uniform; otherwise leaves the scene as it is.
void detect_plain_background(Scene& s);

// Which pixels of a view show the backdrop, where a scene has one (effects.background), as 1s in a
// [height * width] mask; empty when the scene has none or the view no image. With alpha: alpha below
// kBackdropAlpha. Without (a plain backdrop): the pixels within kBorderTolerance of the background colour
// that the image border reaches through such pixels (4-connected), so a white label inside the object,
// enclosed by its print, is not taken for backdrop. The density stage keeps these rays empty
// (DensityTrainConfig::backdrop_weight): a white fog in front of a white backdrop renders the same white, so
// the colour loss alone leaves it there, and the later stages would stylise it as a haze of floaters.
inline constexpr float kBackdropAlpha = 0.02f;
std::vector<uint8_t> backdrop_pixels(const Scene& s, const View& v);

}  // namespace stylerf::scene
