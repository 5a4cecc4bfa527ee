// What stage 2 trains on, drawn from the training views:
//  - FeatureRaySampler: batches of random rays over every training pixel (scene::RaySampler underneath, so
//    rays are the same as the density stage's), with the view index and pixel position each ray needs to
//    read its relu3_1 target (gather_targets);
//  - PatchSampler: a random patch of one training view for the decoder steps: its rays in row-major order,
//    the ground-truth colours as a [1, 3, h, w] image, and its top-left corner.
// Rays are in the scene's ray space (NDC for forward-facing LLFF), as scene::camera_rays makes them.
// Both samplers keep a pointer to the scene: it must outlive them.
#pragma once
#include <cstdint>
#include <random>
#include <vector>

#include "host/tensor.hpp"
#include "lib/scene/rays.hpp"

namespace stylerf::features {

struct FeatureRays {
  scene::Rays rays;              // origins, directions, rgb and pixel (view * W * H + y * W + x) per ray
  std::vector<int32_t> view;     // [R] training-view index
  std::vector<float> pixel_xy;   // [R][2] pixel-centre positions (x + 0.5, y + 0.5), full resolution
  size_t size() const { return view.size(); }
  host::Tensor view_tensor() const;      // [R] I32, for gather_targets
  host::Tensor pixel_xy_tensor() const;  // [R, 2]
};

// Rays [begin, begin + n) of a batch (one rank's share).
FeatureRays slice(FeatureRays all, size_t begin, size_t n);

class FeatureRaySampler {
 public:
  FeatureRaySampler(const scene::Scene& scene, uint64_t seed);
  FeatureRays next(int batch = 4096);  // uniform over all training pixels, with replacement

 private:
  scene::RaySampler sampler_;
  int width_ = 0;
  size_t per_view_ = 0;
};

struct Patch {
  int view = 0;              // training-view index
  int x0 = 0, y0 = 0;        // top-left pixel, multiples of 4 (a 1/4-res rendering lines up with the targets)
  int width = 0, height = 0; // full-resolution size, multiples of 8 (VGG of the decoded patch needs them)
  int stride = 1;            // rays per stride x stride block of pixels
  scene::Rays rays;          // (height / stride) x (width / stride) rays, row-major, through block centres;
                             // rays.rgb is the pixel's colour when stride is 1, empty otherwise
  std::vector<float> rgb;    // [3][height][width] ground truth at full resolution
  host::Tensor rgb_tensor() const;  // [1, 3, height, width]
};

// Patches of size x size pixels (size a positive multiple of 8), or, where an image is smaller, the image
// cropped to a multiple of 8 along that axis. Images under 8 pixels along an axis are refused.
class PatchSampler {
 public:
  PatchSampler(const scene::Scene& scene, uint64_t seed, int size = 256);
  int width() const { return width_; }
  int height() const { return height_; }
  // A uniformly random training view and corner. stride 1: one ray per pixel (the paper profile); stride 4:
  // one ray per 4x4 block, at its centre (the fast profile, features rendered at relu3_1's resolution);
  // stride 2 lies between.
  Patch next(int stride = 1);
  // The same draw from the caller's generator (a draw that depends only on the caller's seed).
  Patch next(int stride, std::mt19937_64& rng) const;
  // The patch of a given view and corner (checked: multiples of 4, inside the image).
  Patch at(int view, int x0, int y0, int stride = 1) const;

 private:
  const scene::Scene* scene_;
  std::mt19937_64 rng_;
  int width_ = 0, height_ = 0;
};

}  // namespace stylerf::features
