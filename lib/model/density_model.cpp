#include "lib/model/density_model.hpp"

#include "lib/render/composite_values.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "host/error.hpp"
#include "host/runtime.hpp"

namespace stylerf::model {

using host::Error;
using nlohmann::json;

// ---- config ------------------------------------------------------------------------------------------------
json DensityModelConfig::to_json() const {
  return json{{"density_rank", density_rank},
              {"app_rank", app_rank},
              {"activation", act == field::DensityActivation::Relu ? "relu" : "softplus"},
              {"view_dependent", view_dependent},
              {"basis_dim", basis_dim},
              {"hidden", hidden},
              {"view_pe", view_pe},
              {"distance_scale", distance_scale},
              {"step_ratio", step_ratio},
              {"weight_threshold", weight_threshold},
              {"mask_threshold", mask_threshold},
              {"init_scale", init_scale},
              {"shading", deferred_shading ? "deferred" : "per-sample"}};
}

DensityModelConfig DensityModelConfig::from_json(const json& j) {
  DensityModelConfig c;
  c.density_rank = j.at("density_rank").get<std::array<int, 3>>();
  c.app_rank = j.at("app_rank").get<std::array<int, 3>>();
  c.act = field::parse_density_activation(j.at("activation").get<std::string>());
  c.view_dependent = j.at("view_dependent").get<bool>();
  c.basis_dim = j.at("basis_dim").get<int>();
  c.hidden = j.at("hidden").get<int>();
  c.view_pe = j.at("view_pe").get<int>();
  c.distance_scale = j.at("distance_scale").get<float>();
  c.step_ratio = j.at("step_ratio").get<float>();
  c.weight_threshold = j.at("weight_threshold").get<float>();
  c.mask_threshold = j.at("mask_threshold").get<float>();
  c.init_scale = j.at("init_scale").get<float>();
  // Checkpoints from before deferred shading have no "shading": they shade per sample.
  const std::string shading = j.value("shading", std::string("per-sample"));
  if (shading != "per-sample" && shading != "deferred")
    throw Error("unknown shading '" + shading + "' (per-sample, deferred)");
  c.deferred_shading = shading == "deferred";
  return c;
}

static field::AppearanceHeadConfig head_config(const DensityModelConfig& cfg) {
  field::AppearanceHeadConfig h;
  h.features = cfg.app_rank[0] + cfg.app_rank[1] + cfg.app_rank[2];
  h.basis_dim = cfg.basis_dim;
  h.hidden = cfg.hidden;
  h.view_dependent = cfg.view_dependent;
  h.view_pe = cfg.view_pe;
  return h;
}

// ---- model -------------------------------------------------------------------------------------------------
DensityModel DensityModel::create(const scene::Scene& scene, const DensityModelConfig& cfg, std::array<int, 3> res,
                                  uint64_t seed) {
  DensityModel m;
  m.cfg = cfg;
  Geometry& g = m.geo;
  for (int a = 0; a < 3; ++a) {
    g.box_lo[a] = scene.aabb[0][a];
    g.box_hi[a] = scene.aabb[1][a];
  }
  g.near = scene.near;
  g.far = scene.far;
  g.ndc = scene.effects.ndc;
  g.ert_threshold = Geometry::default_ert_threshold(g.ndc);
  g.has_background = scene.effects.background;
  g.background = scene.effects.background_rgb;
  if (scene.effects.background_shell && !g.ndc && !g.has_background) {
    g.shell = BackgroundShell{scene.shell_radius, kShellMapHeight, kShellMapWidth};
    // Grey at first: the surroundings' colour is learnt like the grids' (group 0).
    m.shell_map.value = Tensor::full({g.shell.texels(), 3}, 0.5f, "background shell colours");
  }
  g.act = cfg.act;
  g.step_ratio = cfg.step_ratio;
  g.distance_scale = cfg.distance_scale;
  g.weight_threshold = cfg.weight_threshold;
  g.density = field::VMGrid::create(res, cfg.density_rank, cfg.init_scale, seed * 3 + 1);
  m.rgb = RgbHead(field::VMGrid::create(res, cfg.app_rank, cfg.init_scale, seed * 3 + 2),
                  field::AppearanceHead::create(head_config(cfg), seed * 3 + 3), cfg.deferred_shading);
  g.update_step();
  return m;
}

void DensityModel::upsample(std::array<int, 3> new_res) {
  geo.density = field::resample(geo.density, new_res);
  rgb.set_app(field::resample(rgb.app(), new_res));
  geo.update_step();
}

void DensityModel::update_alpha_mask(std::array<int, 3> mask_res) {
  geo.mask = field::build_alpha_mask(geo.density, geo.act, mask_res, geo.mask_step, cfg.mask_threshold);
}

GridCrop DensityModel::occupied_crop() const {
  GridCrop c;
  c.res = res();
  const field::AlphaMask& mask = geo.mask;
  if (!mask.voxels.defined() || mask.empty()) return c;
  for (int a = 0; a < 3; ++a) {
    const int n = c.res[a];
    // Grid points are at -1 + 2 i / (n - 1); snap the occupied box outwards to them.
    int i0 = static_cast<int>(std::floor((mask.lo[a] + 1.0f) * 0.5f * (n - 1)));
    int i1 = static_cast<int>(std::ceil((mask.hi[a] + 1.0f) * 0.5f * (n - 1)));
    i0 = std::clamp(i0, 0, n - 1);
    i1 = std::clamp(i1, 0, n - 1);
    if (i1 - i0 < 1) i1 = std::min(n - 1, i0 + 1), i0 = i1 - 1;
    c.res[a] = i1 - i0 + 1;
    c.lo[a] = -1.0f + 2.0f * i0 / float(n - 1);
    c.hi[a] = -1.0f + 2.0f * i1 / float(n - 1);
  }
  return c;
}

Tensor crop_like_grid(const field::VMGrid& g, const Tensor& t, const GridCrop& c) {
  auto view = field::VMGrid::from_params(g.res, g.rank, t);
  return field::resample(view, c.res, c.lo, c.hi).params;
}

void DensityModel::apply_crop(const GridCrop& c) {
  std::array<float, 3> lo{}, hi{};
  for (int a = 0; a < 3; ++a) {
    const float s = geo.box_hi[a] - geo.box_lo[a];
    lo[a] = geo.box_lo[a] + (c.lo[a] + 1.0f) * 0.5f * s;
    hi[a] = geo.box_lo[a] + (c.hi[a] + 1.0f) * 0.5f * s;
  }
  geo.density = field::resample(geo.density, c.res, c.lo, c.hi);
  rgb.set_app(field::resample(rgb.app(), c.res, c.lo, c.hi));
  geo.box_lo = lo;
  geo.box_hi = hi;
  geo.mask = field::AlphaMask{};
  geo.update_step();
}

std::string DensityModel::describe() const {
  std::ostringstream o;
  const auto a = rgb.app();
  const auto h = rgb.mlp();
  int64_t n = geo.density.numel() + a.numel();
  for (const Tensor* t : {&h.basis, &h.w1, &h.b1, &h.w2, &h.b2, &h.w3, &h.b3}) n += t->numel();
  o << geo.describe() << ", appearance rank " << a.rank[0] << "/" << a.rank[1] << "/" << a.rank[2] << ", "
    << n / 1e6 << "M parameters";
  return o.str();
}

nn::Param& DensityModel::density_param() {
  if (!density_.value.same_buffer(geo.density.params)) {
    density_.value = geo.density.params;
    density_.grad = Tensor();
  }
  return density_;
}

void DensityModel::collect_params(std::vector<nn::Param*>& out) {
  out.push_back(&density_param());
  rgb.collect_params(out);
  if (shell_map.value.defined()) out.push_back(&shell_map);
}

RayResult DensityModel::render(const Tensor& origins, const Tensor& dirs, bool train, uint32_t seed,
                               RayContext* ctx, uint32_t ray_base) const {
  RayOptions opt;
  opt.jitter = train;
  opt.seed = seed;
  opt.ray_base = ray_base;
  RayResult r;
  if (!rgb.deferred()) {
    opt.background = geo.background_tensor();
    r = render_rays(geo, rgb, origins, dirs, opt, ctx);
  } else {
    // Deferred: the pipeline composites appearance features; the head shades them once per ray, and the
    // background goes behind the shaded colour (so not through the pipeline, whose values are features).
    r = render_rays(geo, rgb, origins, dirs, opt, ctx);
    r.value = rgb.shade(r.value, r.kept_acc, cfg.view_dependent ? dirs : Tensor(), ctx ? &ctx->shading : nullptr);
    if (geo.has_background) render::background_forward(r.value, r.acc, geo.background_tensor());
  }
  if (geo.shell.on() && r.value.numel() > 0) {
    render::ShellTaps taps = geo.shell_taps(origins, dirs);
    render::background_shell_forward(r.value, r.acc, shell_map.value, taps);
    if (ctx) ctx->shell = {std::move(taps), r.acc};
  }
  return r;
}

void DensityModel::render_backward(const RayContext& ctx, const Tensor& drgb, const Tensor& dacc_term,
                                   const Tensor& dweights) {
  Tensor& ddensity = density_param().grad_buffer();
  Tensor dacc;  // the backgrounds' gradient w.r.t. the opacity over all samples, plus the caller's
  if (dacc_term.defined()) dacc = dacc_term.clone();
  if (geo.shell.on() && drgb.numel() > 0)
    render::background_shell_backward(drgb, ctx.shell.acc, shell_map.value, ctx.shell.taps, &dacc, dacc.defined(),
                                      &shell_map.grad_buffer());
  if (!rgb.deferred()) {
    render_rays_backward(geo, rgb, ctx, drgb, Tensor(), &ddensity, dacc, dweights);
    return;
  }
  if (geo.has_background) render::background_backward(drgb, geo.background_tensor(), dacc, dacc.defined());
  Tensor dkept_acc;
  const Tensor dF = rgb.shade_backward(*ctx.shading, drgb, dkept_acc);
  render_rays_backward(geo, rgb, ctx, dF, dkept_acc, &ddensity, dacc, dweights);
}

ViewValues DensityModel::render_camera(const scene::Scene& scene, const scene::Camera& cam, int chunk) const {
  return model::render_camera(
      geo, 3, [&](const Tensor& o, const Tensor& d) { return render(o, d, false, 0, nullptr); }, scene, cam, chunk);
}

ViewValues render_view(const DensityModel& m, const scene::Scene& scene, const scene::Camera& cam, int chunk) {
  return m.render_camera(scene, cam, chunk);
}

// ---- checkpoints -------------------------------------------------------------------------------------------
// The format of the density stage's checkpoints (meta["model"], tensors "model.density", "model.app",
// "model.head.*", "model.mask"): unchanged since the stage landed, so earlier checkpoints still load.
void save_model(io::Checkpoint& ck, DensityModel& m) {
  const Geometry& g = m.geo;
  json j;
  j["config"] = m.cfg.to_json();
  j["res"] = m.res();
  j["box_lo"] = g.box_lo;
  j["box_hi"] = g.box_hi;
  j["near"] = g.near;
  j["far"] = g.far;
  j["ndc"] = g.ndc;
  j["has_background"] = g.has_background;
  j["background"] = g.background;
  if (g.shell.on()) j["shell"] = g.shell.to_json();
  j["mask_res"] = g.mask.voxels.defined() ? g.mask.res : std::array<int, 3>{0, 0, 0};
  ck.meta["model"] = j;
  m.save(ck, "model.");
  if (g.mask.voxels.defined()) ck.tensors["model.mask"] = pack_mask(g.mask);
}

DensityModel load_model(const io::Checkpoint& ck) {
  if (!ck.meta.contains("model")) throw Error("checkpoint " + ck.path + " has no model section");
  DensityModel m;
  Geometry& g = m.geo;
  try {
    const json& j = ck.meta.at("model");
    m.cfg = DensityModelConfig::from_json(j.at("config"));
    const auto res = j.at("res").get<std::array<int, 3>>();
    g.box_lo = j.at("box_lo").get<std::array<float, 3>>();
    g.box_hi = j.at("box_hi").get<std::array<float, 3>>();
    g.near = j.at("near").get<float>();
    g.far = j.at("far").get<float>();
    g.ndc = j.at("ndc").get<bool>();
    g.ert_threshold = Geometry::default_ert_threshold(g.ndc);
    g.has_background = j.at("has_background").get<bool>();
    g.background = j.at("background").get<std::array<float, 3>>();
    g.act = m.cfg.act;
    g.step_ratio = m.cfg.step_ratio;
    g.distance_scale = m.cfg.distance_scale;
    g.weight_threshold = m.cfg.weight_threshold;
    const auto mask_res = j.at("mask_res").get<std::array<int, 3>>();
    g.density = field::VMGrid::from_params(
        res, m.cfg.density_rank, ck.device("model.density", {field::VMGrid::numel_of(res, m.cfg.density_rank)}));
    // The head's shapes come from a fresh head of the stored layout; its parameters are then loaded by name.
    m.rgb = RgbHead(field::VMGrid::create(res, m.cfg.app_rank, 0.0f, 0),
                    field::AppearanceHead::create(head_config(m.cfg), 0), m.cfg.deferred_shading);
    m.rgb.load(ck, "model.");
    if (j.contains("shell")) {
      g.shell = BackgroundShell::from_json(j.at("shell"), "checkpoint " + ck.path);
      m.shell_map.value = ck.device("model." + m.shell_map.name, {g.shell.texels(), 3});
    }
    if (mask_res[0] > 0) g.mask = unpack_mask(ck.get("model.mask"), mask_res, ck.path);
  } catch (const json::exception& e) {
    throw Error("checkpoint " + ck.path + ": bad model metadata (" + e.what() + ")");
  }
  g.update_step();
  return m;
}

}  // namespace stylerf::model
