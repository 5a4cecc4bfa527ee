// A viewer's frames: a camera (a training view and an offset, lib/scene/view_offset.hpp), a size, one style
// or two mixed, or two composed by a 3D region, rendered by the style model exactly as `stylerf stylize`
// renders them. The content of the last few cameras is kept, so a new style, mix or region on a still
// camera costs only DST and the decoder (zero-shot: a style is a code, not a model).
// Frames smaller than the scene's own size are previews: one ray a block, and a style's scene statistics
// (the vgg-adain-relu4 decoder's, model::SceneStyleStats: seconds to pool at 800 x 800) only where already
// pooled: a new style's preview re-normalises by its own frame, a mix's interpolates its styles'. The full
// size renders what stylize renders.
// Not thread-safe: one thread (the one using the device) calls render().
#pragma once
#include <array>
#include <atomic>
#include <list>
#include <memory>
#include <string>

#include "lib/io/image.hpp"
#include "lib/model/scene_style_stats.hpp"
#include "lib/model/style_model.hpp"
#include "lib/scene/view_offset.hpp"
#include "lib/viewer/style_library.hpp"

namespace stylerf::viewer {

struct FrameRequest {
  scene::ViewOffset camera;
  int side = 0;                // longer side in pixels
  std::string style, style_b;  // ids; style_b empty: one style
  double mix = 0;              // weight of style_b
  std::string region_shape;    // "", "box" or "sphere": style_b inside, style outside
  double region_scale = 1;
};

struct Frame {
  io::Image image;
  double render_s = 0;
  bool content_cached = false;
  bool preview = false;
};

// Where a region goes unless moved: the scene's middle (object scenes: the middle of the box; forward-facing
// captures: the point the mean view looks at, at the camera path's focus depth), a quarter of its size.
struct RegionPlacement {
  std::array<double, 6> box{};     // x0, y0, z0, x1, y1, z1
  std::array<double, 4> sphere{};  // x, y, z, r
  static RegionPlacement of(const scene::Scene& scene);
  // The region spec (model::Region::parse) of a shape scaled about its centre.
  std::string spec(const std::string& shape, double scale) const;
};

struct FrameRendererOptions {
  int supersample = 0;  // full frames' rays a block (0: the checkpoint's), as stylize --supersample
  float refine_contrast = model::kRefineContrast;
  int chunk = 8192;     // rays per renderer call, as stylize --chunk
  bool decoded_background = false;  // as stylize --decoded-background
  int cached_contents = 4;
};

class FrameRenderer {
 public:
  FrameRenderer(const model::StyleModel& m, const scene::Scene& scene, StyleLibrary& styles,
                style::StyleEncoder& encoder, const model::SceneStyleStats& scene_stats,
                FrameRendererOptions options = {});
  // The scene's own image size (training view 0), and its longer side: the size of a full frame.
  int full_side() const;
  // Throws model::RenderCancelled when `cancel` is raised between renderer calls, host::Error for a
  // request it cannot serve (unknown style, a region without style_b).
  Frame render(const FrameRequest& r, const std::atomic<bool>* cancel = nullptr);
  const RegionPlacement& region_placement() const { return placement_; }
  // A style's code encoded now (an upload), so that its first preview costs a frame only. Throws
  // host::Error for an unknown id.
  void prepare_style(const std::string& id) { styles_.code(id, encoder_); }

 private:
  struct CachedContent {
    std::string key;
    model::StyleModel::CameraContent content;
  };
  const model::StyleModel::CameraContent& content(const FrameRequest& r, const scene::Camera& cam, bool preview,
                                                  const std::atomic<bool>* cancel, bool& cached);
  // The id's code with the scene's statistics attached; with `pooled_only`, without them unless they are
  // pooled already.
  style::StyleCode code_of(const std::string& id, bool pooled_only = false);
  style::StyleCode mixed(const FrameRequest& r, bool preview);

  const model::StyleModel& m_;
  const scene::Scene& scene_;
  StyleLibrary& styles_;
  style::StyleEncoder& encoder_;
  const model::SceneStyleStats& scene_stats_;
  FrameRendererOptions opt_;
  RegionPlacement placement_;
  std::list<CachedContent> contents_;  // most recent first
  std::list<std::pair<std::string, style::StyleCode>> codes_;  // attached codes by id or mix, most recent first
};

}  // namespace stylerf::viewer
