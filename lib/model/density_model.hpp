// The density-stage radiance field (TensoRF VM): the geometry (density grid, box, alpha mask, step;
// lib/model/geometry.hpp) and the RGB value head (appearance grid + MLP; lib/model/rgb_head.hpp).
// Rendering goes through the shared ray pipeline (lib/model/ray_pipeline.hpp) with the scene's background.
// A module (lib/nn/module.hpp): parameters "density" and "app" (group 0, grids) and "head.*" (group 1).
#pragma once
#include <array>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <vector>

#include "lib/io/checkpoint.hpp"
#include "lib/model/geometry.hpp"
#include "lib/model/ray_pipeline.hpp"
#include "lib/model/rgb_head.hpp"
#include "lib/scene/scene.hpp"

namespace stylerf::model {

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
  // Shading (lib/model/rgb_head.hpp): false, per kept sample (TensoRF); true, deferred: once per ray on
  // the weighted mean of its appearance features (one MLP evaluation per ray).
  bool deferred_shading = false;

  nlohmann::json to_json() const;
  static DensityModelConfig from_json(const nlohmann::json& j);
};

// A crop of both grids to a sub-box, in the old grid's normalised coordinates (TensoRF's shrink).
struct GridCrop {
  std::array<int, 3> res{};
  std::array<float, 3> lo{-1, -1, -1}, hi{1, 1, 1};
};

class DensityModel : public nn::Module {
 public:
  DensityModelConfig cfg;
  Geometry geo;
  RgbHead rgb;
  // Captures with real surroundings (geo.shell on): the colour of the background shell's map, [texels, 3]
  // (group 0, with the grids); undefined otherwise.
  nn::Param shell_map{"background_shell", 0, Tensor()};

  static DensityModel create(const scene::Scene& scene, const DensityModelConfig& cfg, std::array<int, 3> res,
                             uint64_t seed);
  std::array<int, 3> res() const { return geo.res(); }
  // Both grids resampled to new_res (bilinear/linear, align_corners); step updated.
  void upsample(std::array<int, 3> new_res);
  // Builds the alpha mask at the given resolution from the density grid.
  void update_alpha_mask(std::array<int, 3> mask_res);
  // The crop of the grid to the mask's occupied box, snapped outwards to grid points (so the crop copies
  // grid values exactly). Returns res == current res and the full box when the mask is empty.
  GridCrop occupied_crop() const;
  // Applies a crop: both grids cropped, the world box shrunk to match, step updated; the mask is dropped
  // (it was built over the old box; the caller rebuilds it).
  void apply_crop(const GridCrop& c);
  std::string describe() const;  // one line: grid, ranks, step, samples per ray, mask occupancy

  // "density" (the geometry's grid) and the RGB head's parameters. The density Param's value is the
  // geometry's grid tensor (refreshed here, so upsampling and cropping need no bookkeeping).
  void collect_params(std::vector<nn::Param*>& out) override;
  nn::Param& density_param();

  // Renders rays with the scene's background (training: jitter with `seed`; `ray_base`: the first ray's
  // index in a larger batch the jitter is drawn for).
  RayResult render(const Tensor& origins, const Tensor& dirs, bool train, uint32_t seed, RayContext* ctx,
                   uint32_t ray_base = 0) const;
  // drgb [R,3] -> gradients accumulated into every parameter. dacc [R] (optional): a gradient w.r.t. each
  // ray's opacity over all samples, from a term on the opacity itself (the density stage's backdrop term).
  // dweights [S] (optional): a gradient w.r.t. every sample's weight (the density stage's distortion term).
  void render_backward(const RayContext& ctx, const Tensor& drgb, const Tensor& dacc = Tensor(),
                       const Tensor& dweights = Tensor());
  // Chunked rendering of a whole camera: the chunk loop of render_camera around render().
  ViewValues render_camera(const scene::Scene& scene, const scene::Camera& cam, int chunk = 8192) const;

 private:
  nn::Param density_{"density", 0, Tensor()};
};

// Crops a tensor laid out like grid g (a parameter, its gradient or an Adam moment) with c.
Tensor crop_like_grid(const field::VMGrid& g, const Tensor& t, const GridCrop& c);

// A whole image in chunks of rays: interleaved rgb [H*W*3], acc and depth [H*W] (depth divided by acc).
ViewValues render_view(const DensityModel& m, const scene::Scene& scene, const scene::Camera& cam,
                       int chunk = 8192);

// The model in a checkpoint (tensors "model.*", meta["model"]) and back.
void save_model(io::Checkpoint& ck, DensityModel& m);
DensityModel load_model(const io::Checkpoint& ck);

}  // namespace stylerf::model
