// Ray marching through the scene box: per ray a slab intersection, evenly spaced samples (step = a fraction
// of a voxel), optional seeded jitter of the first sample, skipping of samples in empty alpha-mask voxels,
// and a compacted sample list (count pass, host exclusive prefix sum, write pass: deterministic).
//
// Samples of ray r: t_i = t_start + step * (i + jitter_r), i = 0, 1, ... while t_i <= t_end, where
// t_start = max(near, t_enter), t_end = min(far, t_exit), jitter_r in [0,1) per ray (0 when off); at most
// max_samples candidates per ray (TensoRF's N_samples cap, applied before mask skipping). Rays missing the
// box (or with t_end < t_start) get none. t is in ray-parameter units: delta = step * |d| * delta_scale is
// the world length of a step (times TensoRF's distance_scale if the trainer wants it).
#pragma once
#include <array>
#include <cstdint>

#include "host/tensor.hpp"
#include "lib/field/alpha_mask.hpp"
#include "lib/field/vm_grid.hpp"

namespace stylerf::render {

using host::Tensor;

struct MarchConfig {
  std::array<float, 3> box_lo{-1, -1, -1}, box_hi{1, 1, 1};  // world aabb
  float near = 0.0f, far = 1e10f;
  float step = 0.01f;       // in t units; see step_for_grid
  int max_samples = 1024;   // candidate cap per ray
  bool jitter = false;      // training: random offset of the first sample
  uint32_t seed = 0;        // jitter seed (vary per iteration)
  // The first ray's index in the jitter's hash: a slice of a batch from ray_base on (one rank's share)
  // draws the jitter the whole batch draws for those rays.
  uint32_t ray_base = 0;
  float delta_scale = 1.0f;
};

// TensoRF's step: mean voxel side of a grid of res points over the box (size / (res - 1)) times step_ratio.
float step_for_grid(const std::array<float, 3>& box_lo, const std::array<float, 3>& box_hi,
                    const std::array<int, 3>& res, float step_ratio = 0.5f);
// TensoRF's candidate cap for a grid: |box diagonal| / step + 1.
int max_samples_for_grid(const std::array<float, 3>& box_lo, const std::array<float, 3>& box_hi, float step);

struct Samples {
  int64_t count = 0;   // S
  Tensor positions;    // [S,3] normalised to [-1,1]^3 by the box
  Tensor t;            // [S]   ray parameter
  Tensor deltas;       // [S]   step * |d| * delta_scale
  Tensor ray_index;    // [S]   I32: which ray
  Tensor ray_offset;   // [R]   I32: first sample of ray r
  Tensor ray_count;    // [R]   I32: samples of ray r (consecutive)
  Tensor sigma;        // [S]   density, when marched with a DensityMarch (else undefined)
};

// Early ray termination: march with the density grid and stop each ray after the sample that brings
// its transmittance below ert_threshold (kernels/march_density.cl). sigma is then computed by the march
// (equal to field::density_forward at the sample positions) and returned in Samples::sigma. Samples past
// the stop would weigh less than ert_threshold; the ray's opacity changes by less than that.
struct DensityMarch {
  const field::VMGrid* grid = nullptr;
  field::DensityActivation act = field::DensityActivation::Softplus;
  float ert_threshold = 1e-4f;  // in (0, 1)
};

// Checks what an op over a sample list reads: ray_offset and ray_count defined, I32 and [R] alike.
// Returns R.
int64_t check_ray_lists(const Tensor& ray_offset, const Tensor& ray_count, const char* op);

// origins, dirs: [R,3] F32, world. mask may be null (no skipping); its voxels are U8 [mz, my, mx].
// density: null for plain marching (every candidate the mask keeps), else early termination.
Samples march(const Tensor& origins, const Tensor& dirs, const MarchConfig& cfg, const field::AlphaMask* mask,
              const DensityMarch* density = nullptr);

}  // namespace stylerf::render
