// The style stage's multi-view term: a second training camera that sees the surface of the step's patch
// renders and decodes its own patch under the same style; that picture, warped into the first patch by the
// rendered geometry (lib/eval/warp.hpp, the correspondence `eval table` scores consistency with), is
// compared with the first on the pixels both see:
//   L = weight x mean over those pixels and the 3 channels of (a(p) - b(w(p)))^2,   b bilinear at w(p),
// and both pictures get its gradient. DST is the same for a 3D point from every view; what makes two views
// of one surface disagree is the 2D part after it (VGG's tail, the re-normalisation, the decoder), which
// only this term shows two cameras at once.
//
// Host-side: a 256 px patch is 65k pixels, and the correspondence is the consistency metric's own code.
#pragma once
#include <cstdint>
#include <random>
#include <vector>

#include "lib/eval/warp.hpp"
#include "lib/io/image.hpp"
#include "lib/scene/scene.hpp"

namespace stylerf::train {

// The camera of a patch cut from a view at (x0, y0), width x height pixels.
scene::Camera patch_camera(const scene::Camera& view, int x0, int y0, int width, int height);

// A rendered patch's geometry at full resolution from its map (map_w x map_h blocks of stride x stride
// pixels, one ray at each block's centre): the depth sums (sum w t) and opacities bilinearly between the
// block centres, the depth divided by the opacity (0 where the opacity is 0: empty space).
eval::FrameGeometry patch_geometry(const scene::Camera& camera, int map_w, int map_h, int stride,
                                   const std::vector<float>& depth_sum, const std::vector<float>& acc);

struct SecondPatch {
  int view = -1;  // -1: no training view qualifies (the term is left out of the step)
  int x0 = 0, y0 = 0;
};
// The second camera for a first patch (its geometry, from training view first_view): the centroid X of the
// patch's surface (pixels of opacity >= 0.5 with a depth), then, uniformly among the other training views
// whose centre sees X within max_angle_deg of the first view's direction (both from X) and whose image
// holds X, one view; its patch of patch_w x patch_h (multiples of 4) centred on X's pixel, moved inside.
SecondPatch pick_second_patch(const scene::Scene& scene, const eval::FrameGeometry& first, int first_view,
                              int patch_w, int patch_h, float max_angle_deg, const eval::RaySpace& space,
                              std::mt19937_64& draw);

struct MultiviewLoss {
  double value = 0;     // weight x the mean squared difference (0 where no pixel is valid)
  int64_t pixels = 0;   // valid pixels compared
  io::Image d_first, d_second;  // dL/da, dL/db (planar, the pictures' sizes)
};
// a: the first picture (the correspondence's frame t), b: the second (frame s), planar RGB. An Error names
// a size mismatch or a NaN or infinite value in either picture.
MultiviewLoss multiview_loss(const io::Image& a, const io::Image& b, const eval::Correspondence& c, float weight);

}  // namespace stylerf::train
