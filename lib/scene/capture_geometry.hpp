// The geometry decisions shared by the loaders of real captures (LLFF, COLMAP, nerfstudio): forward-facing
// (NDC) or object-centric from the camera layout, the normalisation of the poses, and near/far and the box.
// The rule is LLFF's (see llff_loader.hpp); a COLMAP or nerfstudio copy of a capture therefore gets the same
// decision, bounds and box as the LLFF original, up to the scale of its world.
#pragma once
#include <string>
#include <vector>

#include "lib/scene/poses.hpp"
#include "lib/scene/scene.hpp"

namespace stylerf::scene {

// Every 8th view (0, 8, 16, ...) is held out for testing, LLFF's convention, in every capture format.
constexpr int kHoldOutEvery = 8;

// A number for messages and notes, with `precision` significant digits.
std::string fmt_number(double v, int precision = 4);

struct CaptureView {
  Pose pose;                    // camera-to-world, OpenGL axes, in the file's world
  double near = 0, far = 0;     // depth bounds of the content this camera sees (world units); 0 = unknown
  double tan_x = 0, tan_y = 0;  // half field of view tangents: 0.5 * width / fx, 0.5 * height / fy
};

// Decides forward-facing vs object-centric, normalises the poses in place (as the LLFF loader does) and
// fills s.format ("<kind>-forward" or "<kind>-object"), s.effects.ndc (opts.ndc may force it), s.near,
// s.far, s.aabb, s.depth_near, s.depth_far, s.ndc_near and notes giving the reasons.
// When no view has bounds (near == 0 for all: nerfstudio without points) they are assumed from the layout:
// forward-facing: nearest content at 3x, farthest at 20x the RMS distance of the cameras from their mean
// position (LLFF's fern has 4.9x, horns 3.0x); object-centric: a box of half-size half the nearest camera's
// distance from the focus point, near/far where rays enter and leave it. Either way a note says so.
// Throws (naming `what`) when some views have bounds and others not, or bounds are not 0 < near < far.
void normalise_capture(std::vector<CaptureView>& views, const std::string& kind, const LoadOptions& opts, Scene& s,
                       const std::string& what);

}  // namespace stylerf::scene
