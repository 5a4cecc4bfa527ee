// The geometry of a radiance field: the density VM grid, the scene box, the near/far range, the alpha
// mask and the sample step: everything the ray pipeline (lib/model/ray_pipeline.hpp) needs to decide
// where samples go and how much each one weighs. Trained in stage 1 (lib/model/density_model.hpp), then
// frozen: stages 2 and 3 load it from a density checkpoint and never change it.
//
// Units: t and depth are in the ray space (world distance along unit rays; the NDC parameter in [0,1]
// for NDC scenes). delta = step * |d| * distance_scale (TensoRF's distance_scale 25).
#pragma once
#include <array>
#include <nlohmann/json.hpp>
#include <string>

#include "host/tensor.hpp"
#include "lib/field/alpha_mask.hpp"
#include "lib/field/vm_grid.hpp"
#include "lib/render/background_shell.hpp"
#include "lib/render/ray_march.hpp"

namespace stylerf::io {
struct Checkpoint;
struct HostTensor;
}  // namespace stylerf::io

namespace stylerf::model {

using host::Tensor;

// Captures with real surroundings: the sphere their background is painted on and its map's size in texels
// (lib/render/background_shell.hpp). Each stage's model holds its own map (stage 1 colours, stage 2
// features); the geometry says where it is. Radius 0: no shell.
struct BackgroundShell {
  float radius = 0;
  int height = 0, width = 0;
  bool on() const { return radius > 0; }
  int64_t texels() const { return int64_t(height) * width; }
  nlohmann::json to_json() const;
  static BackgroundShell from_json(const nlohmann::json& j, const std::string& where);
};
// The map's size: 1.4 degrees a texel, a few times coarser than the object's pixels, which the
// surroundings can afford (they are out of focus, and only the style stage looks at them as a whole).
inline constexpr int kShellMapHeight = 128, kShellMapWidth = 256;

struct Geometry {
  std::array<float, 3> box_lo{}, box_hi{};
  float near = 0, far = 1;
  bool ndc = false;
  bool has_background = false;
  std::array<float, 3> background{1, 1, 1};
  BackgroundShell shell;
  field::VMGrid density;
  field::DensityActivation act = field::DensityActivation::Softplus;
  field::AlphaMask mask;         // mask.voxels undefined: no mask
  bool use_mask = true;          // false: ignore the mask while marching (bench knob)
  float step_ratio = 0.5f;       // samples per voxel side (TensoRF)
  float distance_scale = 25.0f;  // TensoRF
  float weight_threshold = 1e-4f;  // samples below this weight get no value (TensoRF's app mask)
  // Early ray termination: a ray stops after the sample that takes its transmittance below this (0: off,
  // every candidate is sampled). A run-time knob, not stored: it changes a ray's opacity by less than
  // itself and, at or below weight_threshold, no sample that gets a value. Default: default_ert_threshold.
  float ert_threshold = 1e-4f;
  // 1e-4 for object captures, whose rays turn opaque at the surface (lego: half the samples go, renders
  // 1.9x faster); 0 for NDC scenes, whose rays mostly stay partly transparent to the far plane (fern: 2% of
  // samples go, and the per-ray march costs more than it saves: 5.8 vs 5.0 s a view). bench render.
  static float default_ert_threshold(bool ndc) { return ndc ? 0.0f : 1e-4f; }
  float step = 0;                // t units between samples (derived: update_step)
  float mask_step = 0;           // box-unit step the alpha mask is built with (TensoRF: its stepSize)
  int max_samples = 0;

  std::array<int, 3> res() const { return density.res; }
  std::array<float, 3> box_size() const;
  // Recomputes step / max_samples from the grid resolution and the box (TensoRF's update_stepSize).
  void update_step();
  // A copy (the grids and the mask shared, not copied) whose march samples every `ratio` voxel sides; the
  // mask keeps the step it was built with.
  Geometry with_step_ratio(float ratio) const;
  render::MarchConfig march_config(bool jitter, uint32_t seed, uint32_t ray_base = 0) const;
  const field::AlphaMask* active_mask() const { return (use_mask && mask.voxels.defined()) ? &mask : nullptr; }
  Tensor background_tensor() const;  // [3], undefined when the scene has no background
  // The shell's taps of rays [R, 3] (origins and directions in the ray space); only with a shell.
  render::ShellTaps shell_taps(const Tensor& origins, const Tensor& dirs) const;
  std::string describe() const;      // grid, step, samples per ray, box, mask occupancy

  // Saved as "<prefix>density" + "<prefix>mask" tensors and meta[<prefix>geometry].
  void save(io::Checkpoint& ck, const std::string& prefix) const;
  static Geometry load(const io::Checkpoint& ck, const std::string& prefix);
};

// The alpha mask stored packed, 8 voxels per value (0..255), as TensoRF packs its mask bits: a record of
// the mask training used, not something to recompute from a later grid.
io::HostTensor pack_mask(const field::AlphaMask& m);
field::AlphaMask unpack_mask(const io::HostTensor& t, std::array<int, 3> res, const std::string& path);

}  // namespace stylerf::model
