// Rays on the host: per-pixel rays of a camera and random batches of training pixels with their target
// colours, in world space or NDC. Arrays are [R][3] interleaved float, ready to upload as [R,3] tensors.
//
// World space: origin = camera centre, direction = unit vector through the pixel centre (as TensoRF does
// for Blender), so the ray parameter t is the distance from the camera.
// NDC (forward-facing LLFF, as NeRF/TensoRF): the origin is first moved along the ray to the plane
// z = -near, then origin and direction are projected:
//   o' = (-2fx/W * ox/oz, -2fy/H * oy/oz, 1 + 2 near/oz)
//   d' = (-2fx/W * (dx/dz - ox/oz), -2fy/H * (dy/dz - oy/oz), -2 near/oz)
// so o' + t d' for t in [0, 1] runs from the near plane (NDC z = -1) to infinity (NDC z = 1).
// NDC directions are not normalised (the renderer scales step lengths by |d'|).
#pragma once
#include <array>
#include <cstdint>
#include <random>
#include <vector>

#include "lib/scene/scene.hpp"

namespace stylerf::scene {

struct Rays {
  std::vector<float> origins;     // [R][3]
  std::vector<float> directions;  // [R][3]
  std::vector<float> rgb;         // [R][3] target colours, empty when there is no image
  std::vector<int> pixel;         // [R] optional: view * (W*H) + y * W + x for batches, else empty
  size_t size() const { return origins.size() / 3; }
};

// Rays [begin, begin + n) of a batch (the whole batch when they are all of it: no copy is worth avoiding
// here, the batch is a few thousand rays).
Rays slice(Rays all, size_t begin, size_t n);

// World-space ray through the continuous pixel position (px, py) (pixel centres at +0.5); d unit length.
void pixel_ray(const Camera& cam, float px, float py, float o[3], float d[3]);

// The NDC transform above, in place. W, H, fx, fy come from the camera; `near` is the plane z = -near.
void to_ndc(const Camera& cam, float near, float o[3], float d[3]);

// NDC coordinates of a world point (the same projection as to_ndc; for tests and box checks).
std::array<float, 3> ndc_point(const Camera& cam, float near, const std::array<float, 3>& p);

// All W*H rays of a camera, row-major (y, then x); NDC when the scene's effects say so.
Rays camera_rays(const Scene& scene, const Camera& cam);

// Uniform random batches over every training pixel (with replacement; no index table, so memory does not
// grow with the dataset). Deterministic for a seed.
class RaySampler {
 public:
  RaySampler(const Scene& scene, uint64_t seed);
  Rays next(int batch);
  size_t pixel_count() const { return total_; }

 private:
  const Scene* scene_;
  std::mt19937_64 rng_;
  size_t per_view_, total_;
};

}  // namespace stylerf::scene
