// The style stage's yardstick: for held-out styles and test views, the content and style
// losses (lib/train/style_losses.hpp, the training weights) of our stylised renders and, measured by the
// same VGG with the same mask, of 2D AdaIN applied to the ground-truth views (the per-frame baseline).
// On scenes with a background both are masked by the rendered opacity. Images are cut to multiples of 8
// (VGG's three poolings); the style image is resized to 256 x 256 (the authors' test transform).
// Beside the training losses, a structure score that does not use them: LPIPS between the true view and
// each stylised one (ArtFID's content term), ours against AdaIN's, masked by the same opacity. A low style
// loss bought by painting over the object's detail shows here, not in the loss ratio.
#pragma once
#include <string>
#include <vector>

#include "lib/eval/lpips.hpp"
#include "lib/model/style_model.hpp"
#include "lib/scene/scene.hpp"
#include "lib/style/adain.hpp"
#include "lib/train/style_losses.hpp"

namespace stylerf::train {

// Planar [1, 3, He, We] from an interleaved [H][W][3] image of width W, its top-left He x We.
host::Tensor planar_crop(const std::vector<float>& rgb, int W, int He, int We);
// A camera's opacity per pixel [He * We] (each pixel its stride x stride block's), for images cut to He x We.
std::vector<float> content_opacity_pixels(const model::StyleModel::CameraContent& cc, int stride, int He, int We);
// The loss mask of a camera's content (its opacity per stride x stride block), for images cut to He x We.
OpacityMask content_opacity_mask(const model::StyleModel::CameraContent& cc, int stride, int He, int We);

struct StyleEvalRow {
  std::string style;
  double ours_content = 0, ours_style = 0, adain_content = 0, adain_style = 0;  // means over the views
  std::array<double, nn::VggFeatures::kCount> ours_style_tap{}, adain_style_tap{};  // the style terms per VGG tap
  // LPIPS(true view, stylised view), means over the views it was measured on: none when
  // StyleEvalOptions::lpips is unset or the views are below the trunk's smallest side.
  double ours_lpips = 0, adain_lpips = 0;
  int structure_views = 0;
  // StyleEvalOptions::vgg_map_row: ours on the true view's own relu3_1 map instead of the radiance field's
  // (SICT with the map's statistics, DST, the decoder): what the style module does with perfect content.
  // Set apart from the rendered row, it tells the structure the field's map loses from what the style loses.
  double vgg_map_content = 0, vgg_map_style = 0, vgg_map_lpips = 0;
};
struct StyleEvalOptions {
  int views = 5;            // test views, evenly spaced (0: all)
  std::string image_dir;    // non-empty: writes <style>_view<i>.png (truth | ours | AdaIN) for the first view
  int supersample = 1;      // content rays per block and axis (StyleModel::render_camera_content)
  float refine_contrast = model::kRefineContrast;  // those rays only where the map has edges; 0: every block
  const eval::Lpips* lpips = nullptr;  // set: the structure score (StyleEvalRow::*_lpips) too
  bool vgg_map_row = false;            // also StyleEvalRow::vgg_map_* (a diagnosis; one more 2D frame a style)
  std::ostream* log = nullptr;
};
std::vector<StyleEvalRow> evaluate_styles(const model::StyleModel& m, nn::VggEncoder& vgg, style::AdainModel& adain,
                                          const scene::Scene& scene, const std::vector<std::string>& styles,
                                          const StyleEvalOptions& opt);

}  // namespace stylerf::train
