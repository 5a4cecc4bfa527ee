// Warping one rendered frame into another by the scene's own geometry (no optical flow): each pixel p of
// frame t becomes a world point X from frame t's rendered depth, X is projected into frame s, and the
// correspondence is kept only where frame s sees the same surface there.
//
// Validity of a pixel p of frame t (each reason is counted in WarpStats):
//  - background: on scenes with a background colour, p's opacity is below min_opacity (empty space has
//    no depth), or the opacity of frame s at any of the 2x2 pixels the bilinear sample reads is;
//  - no depth: the depth is infinite, or 0 (world space: a point at the camera centre, which is what a
//    renderer reports for an empty ray), or at the NDC far end (t >= ndc_far: a point at infinity, where
//    depth no longer pins down a 3D point);
//  - off image: X lies behind camera s, or lands outside the pixel centres of frame s (bilinear sampling
//    needs its 2x2 neighbours: x in [0.5, W - 0.5], y in [0.5, H - 0.5]);
//  - occluded: at one of those 2x2 pixels, the distance from camera s to frame s's own rendered surface
//    differs from the distance to X by more than depth_tolerance x the latter (X is hidden there, or
//    the sample would straddle a depth edge and mix two surfaces).
//
// A NaN depth or opacity is not a reason to leave a pixel out but an Error naming the pixel: renderers
// report empty rays as 0, so NaN means the render failed.
//
// Depths are in the scene's ray space (scene.hpp): the distance along unit rays, or the NDC parameter in
// [0, 1] for NDC scenes, which world_point maps back to the world (the inverse of rays.hpp's to_ndc).
#pragma once
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "lib/io/image.hpp"
#include "lib/scene/scene.hpp"

namespace stylerf::eval {

// How a ray-space depth becomes a world point.
struct RaySpace {
  bool ndc = false;
  float ndc_near = 1;  // the world plane z = -ndc_near NDC rays start on
  static RaySpace of(const scene::Scene& scene);
};

// One rendered frame's geometry: its camera, its depth (ray space, already divided by the opacity) and
// its opacity, both [height * width], row-major.
struct FrameGeometry {
  scene::Camera camera;
  std::vector<float> depth, opacity;
};

struct WarpOptions {
  float depth_tolerance = 0.03f;  // relative
  bool mask_background = false;   // scenes with a background colour
  float min_opacity = 0.5f;       // with mask_background
  float ndc_far = 0.999f;         // NDC depths at or beyond this are at infinity
};

struct WarpStats {
  int64_t valid = 0, background = 0, no_depth = 0, off_image = 0, occluded = 0;
  int64_t pixels() const { return valid + background + no_depth + off_image + occluded; }
  double valid_fraction() const { return pixels() ? double(valid) / double(pixels()) : 0.0; }
};

// Where each pixel of frame t lands in frame s (continuous pixel coordinates, centres at +0.5) and
// whether the correspondence is valid.
struct Correspondence {
  int width = 0, height = 0;   // frame t's
  std::vector<float> x, y;     // [H*W] landing positions in frame s (meaningful where valid)
  std::vector<uint8_t> valid;  // [H*W] 1 = valid
  WarpStats stats;
};

// Captures with a background shell (model::BackgroundShell: a sphere of `radius` about the world origin,
// painted with the room): a pixel whose box opacity is below `min_opacity` shows mostly the shell, so the
// shell is its surface. Its depth becomes where its ray leaves the sphere and its opacity 1; pixels the box
// holds keep theirs. Without it the room, most of such a frame, had either no depth or that of the box's
// faint remainder, and the metric scored the object and a patchwork of occlusions around it. World space
// only (shell captures are never NDC); a camera outside the sphere (no exit ahead) leaves the frame as is.
void add_shell_surface(FrameGeometry& f, float radius, float min_opacity = 0.5f);

// World point of pixel position (px, py) of `cam` at ray-space depth t. `finite` (optional) is set to
// false for points at infinity (NDC t at or beyond ndc_far), where the returned point is meaningless.
std::array<double, 3> world_point(const scene::Camera& cam, double px, double py, double t, const RaySpace& space,
                                  double ndc_far = 0.999, bool* finite = nullptr);

Correspondence correspond(const FrameGeometry& t, const FrameGeometry& s, const RaySpace& space,
                          const WarpOptions& opt = {});

// The bilinear sample of a width x height frame at a landing position (continuous pixel coordinates, centres
// at +0.5), clamped to the pixel centres: its 2x2 pixels and their weights (summing to 1).
struct BilinearTaps {
  int x[4], y[4];
  double w[4];
};
BilinearTaps bilinear_taps(double qx, double qy, int width, int height);

// Frame s sampled (bilinearly) at the correspondence: an image on frame t's pixel grid. Pixels that are
// not valid take `fill`'s value (frame t itself, for masked comparisons: no difference where nothing
// is compared).
io::Image warp_image(const io::Image& s, const Correspondence& c, const io::Image& fill);

// sqrt(mean over valid pixels and the 3 channels of (a - b)^2); NaN when no pixel is valid. A NaN or
// infinite value in either image is an Error naming its pixel (a failed render must not score).
double masked_rmse(const io::Image& a, const io::Image& b, const std::vector<uint8_t>& valid);

// The validity mask as weights [H*W] (1 / 0), for masked LPIPS.
std::vector<float> mask_weights(const std::vector<uint8_t>& valid);

}  // namespace stylerf::eval
