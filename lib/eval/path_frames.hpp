// The frames a consistency measurement compares (consistency.hpp): the first cameras of a path, rendered
// by one method, plus the geometry every method is warped with.
//  - geometry: opacity and depth from a checkpoint's frozen density grid alone (model::render_geometry);
//  - rgb: the density stage's own colours (the floor: a radiance field is consistent by construction);
//  - adain: per-frame 2D AdaIN of those RGB frames (alpha 1), the image-space baseline;
//  - stylerf: the style stage, zero-shot, with a style's code.
// Frames are planar images of the cameras' size, over the scene's background where it has one.
#pragma once
#include <string>
#include <vector>

#include "lib/eval/warp.hpp"
#include "lib/io/image.hpp"
#include "lib/model/density_model.hpp"
#include "lib/model/style_model.hpp"
#include "lib/style/adain.hpp"

namespace stylerf::eval {

// The first `frames` cameras of the scene's default path of `path_frames` (a video's spacing), each
// resized so its longer side is `size` (0: the scene's size).
std::vector<scene::Camera> path_cameras(const scene::Scene& scene, int frames, int path_frames, int size);

std::vector<FrameGeometry> render_path_geometry(const model::Geometry& g, const scene::Scene& scene,
                                                const std::vector<scene::Camera>& cams, int chunk = 8192);

// geometry (optional): each frame's opacity and depth from the same render, equal to render_path_geometry's
// on the model's geometry (the same march and weights; only the value differs).
std::vector<io::Image> rgb_frames(const model::DensityModel& m, const scene::Scene& scene,
                                  const std::vector<scene::Camera>& cams, int chunk = 8192,
                                  std::vector<FrameGeometry>* geometry = nullptr);

// The style image at the size StyleRF's style codes use (stylize: 256x256), so both methods see the same
// pixels of the style.
constexpr int kStyleSide = 256;
io::Image load_style_for_eval(const std::string& path);

// Each frame resized to multiples of 8 (AdaIN's VGG pools three times), stylised at alpha 1, resized back
// and clamped to [0, 1].
std::vector<io::Image> adain_frames(style::AdainModel& adain, const std::vector<io::Image>& content,
                                    const io::Image& style_image);

// The style-independent part of StyleRF's frames (SICT's output, opacity, depth): rendered once per
// camera and shared by every style scored on the same frames, since it is most of a frame's cost (fern
// at 1008x756 with 3x3 rays a block: ~35 of 40 s). supersample: content rays per feature-map block and
// axis, refined where the map has edges (StyleModel::render_camera_content).
std::vector<model::StyleModel::CameraContent> content_frames(const model::StyleModel& m, const scene::Scene& scene,
                                                              const std::vector<scene::Camera>& cams,
                                                              int chunk = 4096, int supersample = 1,
                                                              float refine_contrast = model::kRefineContrast);

// The frames of one style from content_frames' contents of the same cameras. over_background: composite
// over the scene's background by the rendered opacity (as `stylize` does).
std::vector<io::Image> stylerf_frames(const model::StyleModel& m,
                                      const std::vector<model::StyleModel::CameraContent>& contents,
                                      const std::vector<scene::Camera>& cams, const style::StyleCode& code,
                                      bool over_background);

// Both of the above for one style.
std::vector<io::Image> stylerf_frames(const model::StyleModel& m, const scene::Scene& scene,
                                      const std::vector<scene::Camera>& cams, const style::StyleCode& code,
                                      bool over_background, int chunk = 4096, int supersample = 1,
                                      float refine_contrast = model::kRefineContrast);

// Interleaved [h][w][3] -> planar image (no clamping).
io::Image planar_image(const std::vector<float>& interleaved, int width, int height);

}  // namespace stylerf::eval
