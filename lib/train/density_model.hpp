// The density-stage radiance field (TensoRF VM): a density grid, an appearance grid, the appearance head,
// the scene box and the alpha mask, with the one ray renderer used by training, evaluation and rendering.
//
// render_rays (TensoRF's forward, lib/render + lib/field ops):
//   march (jitter when training, alpha-mask skip) -> sigma = density grid at the samples -> weights
//   (composite with no colour) -> keep samples with w >= weight_threshold -> appearance features and the
//   head on the kept samples only -> colours scattered back (0 for dropped samples) -> composite rgb, acc,
//   depth (+ (1 - acc) * background when the scene has one).
// Its backward: composite -> (dsigma, dvalues) ; dvalues of kept samples -> head -> features_backward ;
// dsigma -> density_backward. The sample selection itself has no gradient (as TensoRF's app_mask).
//
// Units: t and depth are in the ray space (world distance along unit rays; the NDC parameter in [0,1]
// for NDC scenes). delta = step * |d| * distance_scale (TensoRF's distance_scale 25).
#pragma once
#include <array>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <vector>

#include "host/tensor.hpp"
#include "lib/field/alpha_mask.hpp"
#include "lib/field/appearance_head.hpp"
#include "lib/field/vm_grid.hpp"
#include "lib/io/checkpoint.hpp"
#include "lib/render/composite.hpp"
#include "lib/render/ray_march.hpp"
#include "lib/scene/scene.hpp"

namespace stylerf::train {

using host::Tensor;

struct DensityModelConfig {
  std::array<int, 3> density_rank{16, 16, 16};  // TensoRF lego config (LLFF: 16, 4, 4)
  std::array<int, 3> app_rank{48, 48, 48};      // TensoRF lego config (LLFF: 48, 12, 12)
  field::DensityActivation act = field::DensityActivation::Softplus;
  bool view_dependent = false;
  int basis_dim = 27, hidden = 128, view_pe = 2;
  float distance_scale = 25.0f;   // TensoRF
  float step_ratio = 0.5f;        // samples every half voxel
  float weight_threshold = 1e-4f; // TensoRF rayMarch_weight_thres: samples below get no appearance
  float mask_threshold = 1e-4f;   // TensoRF alpha_mask_thre
  float init_scale = 0.1f;        // TensoRF: factors ~ 0.1 * N(0, 1)

  nlohmann::json to_json() const;
  static DensityModelConfig from_json(const nlohmann::json& j);
};

// A crop of both grids to a sub-box, in the old grid's normalised coordinates (TensoRF's shrink).
struct GridCrop {
  std::array<int, 3> res{};
  std::array<float, 3> lo{-1, -1, -1}, hi{1, 1, 1};
};

struct DensityModel {
  DensityModelConfig cfg;
  std::array<float, 3> box_lo{}, box_hi{};
  float near = 0, far = 1;
  bool ndc = false;
  bool has_background = false;
  std::array<float, 3> background{1, 1, 1};
  field::VMGrid density, app;
  field::AppearanceHead head;
  field::AlphaMask mask;  // mask.voxels null: no mask
  bool use_mask = true;   // false: ignore the mask while marching (bench knob)
  float step = 0;         // t units between samples (derived: update_step)
  float mask_step = 0;    // box-unit step the alpha mask is built with (TensoRF: its stepSize)
  int max_samples = 0;

  static DensityModel create(const scene::Scene& scene, const DensityModelConfig& cfg, std::array<int, 3> res,
                             uint64_t seed);
  std::array<int, 3> res() const { return density.res; }
  std::array<float, 3> box_size() const;
  // Recomputes step / max_samples from the grid resolution and the box (TensoRF's update_stepSize).
  void update_step();
  // Both grids resampled to new_res (bilinear/linear, align_corners).
  void upsample(std::array<int, 3> new_res);
  // Builds the alpha mask at the given resolution from the density grid.
  void update_alpha_mask(std::array<int, 3> mask_res);
  // The crop of the grid to the mask's occupied box, snapped outwards to grid points (so the crop copies
  // grid values exactly). Returns res == current res and the full box when the mask is empty.
  GridCrop occupied_crop() const;
  // Applies a crop: both grids cropped, the world box shrunk to match, step updated; the mask is dropped
  // (it was built over the old box; the caller rebuilds it).
  void apply_crop(const GridCrop& c);
  render::MarchConfig march_config(bool train, uint32_t seed) const;
  Tensor background_tensor() const;  // [3], undefined when the scene has no background
  int64_t param_count() const;
  std::string describe() const;  // one line: grid, ranks, step, samples per ray, mask occupancy
};

// Crops a tensor laid out like grid g (a parameter, its gradient or an Adam moment) with c.
Tensor crop_like_grid(const field::VMGrid& g, const Tensor& t, const GridCrop& c);

struct RayOutputs {
  Tensor rgb;    // [R,3]
  Tensor acc;    // [R]
  Tensor depth;  // [R] sum w t (not divided by acc)
  int64_t samples = 0, kept = 0;
};

// What render_rays_backward needs.
struct RenderCache {
  render::Samples samples;
  Tensor sigma;        // [S]
  render::Kept kept;
  Tensor kept_pos;     // [K,3]
  Tensor values;       // [S,3] colours (0 for dropped samples)
  field::HeadCache head;
  Tensor background;
};

// origins, dirs [R,3] in the ray space. train: jitter the first sample with `seed`.
RayOutputs render_rays(const DensityModel& m, const Tensor& origins, const Tensor& dirs, bool train, uint32_t seed,
                       RenderCache* cache);

struct DensityGrads {
  Tensor density, app;    // accumulated into: zero them before each step
  field::HeadGrads head;  // overwritten
  static DensityGrads zeros_like(const DensityModel& m);
};
// drgb [R,3]: upstream gradient of the composited colour.
void render_rays_backward(const DensityModel& m, const RenderCache& cache, const Tensor& drgb, DensityGrads& grads);

// A whole image in chunks of rays (bounded memory): interleaved rgb [H*W*3], acc and depth [H*W]
// (depth divided by acc where acc > 1e-6, else 0).
struct ViewRender {
  int width = 0, height = 0;
  std::vector<float> rgb, acc, depth;
};
ViewRender render_camera(const DensityModel& m, const scene::Scene& scene, const scene::Camera& cam,
                         int chunk = 8192);

// The model in a checkpoint (tensors "model.*", meta["model"]) and back.
void save_model(io::Checkpoint& ck, const DensityModel& m);
DensityModel load_model(const io::Checkpoint& ck);

// Parameters in a fixed order with their optimiser group: 0 grids, 1 network (basis + MLP).
struct NamedParam {
  std::string name;
  Tensor* param;
  int group;
};
std::vector<NamedParam> named_params(DensityModel& m);
std::vector<Tensor*> grad_list(DensityGrads& g);  // same order as named_params

}  // namespace stylerf::train
