#include "lib/train/density_model.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "host/error.hpp"
#include "host/runtime.hpp"
#include "lib/render/int_tensor.hpp"
#include "lib/scene/rays.hpp"

namespace stylerf::train {

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
              {"init_scale", init_scale}};
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
  for (int a = 0; a < 3; ++a) {
    m.box_lo[a] = scene.aabb[0][a];
    m.box_hi[a] = scene.aabb[1][a];
  }
  m.near = scene.near;
  m.far = scene.far;
  m.ndc = scene.effects.ndc;
  m.has_background = scene.effects.background;
  m.background = scene.effects.background_rgb;
  m.density = field::VMGrid::create(res, cfg.density_rank, cfg.init_scale, seed * 3 + 1);
  m.app = field::VMGrid::create(res, cfg.app_rank, cfg.init_scale, seed * 3 + 2);
  m.head = field::AppearanceHead::create(head_config(cfg), seed * 3 + 3);
  m.update_step();
  return m;
}

std::array<float, 3> DensityModel::box_size() const {
  return {box_hi[0] - box_lo[0], box_hi[1] - box_lo[1], box_hi[2] - box_lo[2]};
}

void DensityModel::update_step() {
  const auto r = res();
  mask_step = render::step_for_grid(box_lo, box_hi, r, cfg.step_ratio);
  if (ndc) {
    // TensoRF's NDC sampling: N = |res| / step_ratio samples evenly over [near, far] of the NDC parameter.
    const double n = std::sqrt(double(r[0]) * r[0] + double(r[1]) * r[1] + double(r[2]) * r[2]) / cfg.step_ratio;
    step = static_cast<float>((far - near) / n);
    max_samples = static_cast<int>(n) + 1;
  } else {
    step = mask_step;
    max_samples = render::max_samples_for_grid(box_lo, box_hi, step);
  }
}

void DensityModel::upsample(std::array<int, 3> new_res) {
  density = field::resample(density, new_res);
  app = field::resample(app, new_res);
  update_step();
}

void DensityModel::update_alpha_mask(std::array<int, 3> mask_res) {
  mask = field::build_alpha_mask(density, cfg.act, mask_res, mask_step, cfg.mask_threshold);
}

GridCrop DensityModel::occupied_crop() const {
  GridCrop c;
  c.res = res();
  if (!mask.voxels || mask.empty()) return c;
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
    const float s = box_hi[a] - box_lo[a];
    lo[a] = box_lo[a] + (c.lo[a] + 1.0f) * 0.5f * s;
    hi[a] = box_lo[a] + (c.hi[a] + 1.0f) * 0.5f * s;
  }
  density = field::resample(density, c.res, c.lo, c.hi);
  app = field::resample(app, c.res, c.lo, c.hi);
  box_lo = lo;
  box_hi = hi;
  mask = field::AlphaMask{};
  update_step();
}

render::MarchConfig DensityModel::march_config(bool train, uint32_t seed) const {
  render::MarchConfig mc;
  mc.box_lo = box_lo;
  mc.box_hi = box_hi;
  mc.near = near;
  mc.far = far;
  mc.step = step;
  mc.max_samples = max_samples;
  mc.jitter = train;
  mc.seed = seed;
  mc.delta_scale = cfg.distance_scale;
  return mc;
}

Tensor DensityModel::background_tensor() const {
  if (!has_background) return Tensor();
  return Tensor::from_host({background[0], background[1], background[2]}, {3}, "background colour");
}

int64_t DensityModel::param_count() const {
  int64_t n = density.numel() + app.numel();
  auto& h = const_cast<field::AppearanceHead&>(head);
  for (Tensor* t : h.params()) n += t->numel();
  return n;
}

std::string DensityModel::describe() const {
  std::ostringstream o;
  const auto r = res();
  o << "grid " << r[0] << "x" << r[1] << "x" << r[2] << ", density rank " << density.rank[0] << "/"
    << density.rank[1] << "/" << density.rank[2] << ", appearance rank " << app.rank[0] << "/" << app.rank[1] << "/"
    << app.rank[2] << ", " << param_count() / 1e6 << "M parameters, step " << step << " (<= " << max_samples
    << " samples/ray), box [" << box_lo[0] << ", " << box_lo[1] << ", " << box_lo[2] << "] .. [" << box_hi[0] << ", "
    << box_hi[1] << ", " << box_hi[2] << "]";
  if (mask.voxels)
    o << ", alpha mask " << mask.res[0] << "x" << mask.res[1] << "x" << mask.res[2] << " ("
      << 100.0 * double(mask.occupied) / (double(mask.res[0]) * mask.res[1] * mask.res[2]) << "% occupied"
      << (use_mask ? "" : ", not used") << ")";
  return o.str();
}

// ---- rendering ---------------------------------------------------------------------------------------------
static RayOutputs empty_outputs(const DensityModel& m, int64_t R) {
  RayOutputs out;
  std::vector<float> rgb(size_t(R) * 3, 0.0f);
  if (m.has_background)
    for (int64_t r = 0; r < R; ++r)
      for (int c = 0; c < 3; ++c) rgb[size_t(r) * 3 + c] = m.background[c];
  out.rgb = Tensor::from_host(rgb, {R, 3}, "rendered rgb");
  out.acc = Tensor::zeros({R}, "rendered acc");
  out.depth = Tensor::zeros({R}, "rendered depth");
  return out;
}

RayOutputs render_rays(const DensityModel& m, const Tensor& origins, const Tensor& dirs, bool train, uint32_t seed,
                       RenderCache* cache) {
  const int64_t R = origins.dim(0);
  const field::AlphaMask* mask = (m.use_mask && m.mask.voxels) ? &m.mask : nullptr;
  render::Samples s = render::march(origins, dirs, m.march_config(train, seed), mask);
  if (cache) *cache = RenderCache{};
  if (cache) cache->samples = s;
  if (s.count == 0) return empty_outputs(m, R);

  Tensor sigma = field::density_forward(m.density, s.positions, m.cfg.act);
  // Weights first (no colour), so only samples that count get appearance features.
  Tensor no_colour = Tensor::zeros({s.count, 1}, "no colour");
  render::Composited w = render::composite_forward(s, sigma, no_colour, Tensor());
  render::Kept k = render::keep_by_weight(s, w.weights, m.cfg.weight_threshold);

  Tensor values;
  Tensor kept_pos;
  field::HeadCache hc;
  if (k.count > 0) {
    kept_pos = render::gather_rows(s.positions, k.index, k.count);
    Tensor feat = field::features_forward(m.app, kept_pos);
    Tensor view_dirs;
    if (m.cfg.view_dependent) {
      Tensor ray_of = render::gather_rows(s.ray_index, k.index, k.count);
      view_dirs = render::gather_rows(dirs, ray_of, k.count);
    }
    Tensor rgb_k = field::appearance_forward(m.head, feat, view_dirs, cache ? &hc : nullptr);
    values = render::scatter_rows(rgb_k, k.index, s.count);
  } else {
    values = Tensor::zeros({s.count, 3}, "sample colours");
  }
  Tensor bg = m.background_tensor();
  render::Composited c = render::composite_forward(s, sigma, values, bg);
  RayOutputs out;
  out.rgb = c.value;
  out.acc = c.acc;
  out.depth = c.depth;
  out.samples = s.count;
  out.kept = k.count;
  if (cache) {
    cache->sigma = sigma;
    cache->kept = k;
    cache->kept_pos = kept_pos;
    cache->values = values;
    cache->head = hc;
    cache->background = bg;
  }
  return out;
}

DensityGrads DensityGrads::zeros_like(const DensityModel& m) {
  DensityGrads g;
  g.density = Tensor::zeros(m.density.params.shape(), "density grid gradient");
  g.app = Tensor::zeros(m.app.params.shape(), "appearance grid gradient");
  return g;
}

static field::HeadGrads zero_head_grads(const DensityModel& m) {
  field::HeadGrads g;
  auto& h = const_cast<field::AppearanceHead&>(m.head);
  auto src = h.params();
  auto dst = g.params();
  for (size_t i = 0; i < src.size(); ++i) *dst[i] = Tensor::zeros(src[i]->shape(), "head gradient");
  return g;
}

void render_rays_backward(const DensityModel& m, const RenderCache& cache, const Tensor& drgb, DensityGrads& grads) {
  const render::Samples& s = cache.samples;
  if (s.count == 0) {
    grads.head = zero_head_grads(m);
    return;
  }
  render::CompositeGrads cg =
      render::composite_backward(s, cache.sigma, cache.values, cache.background, drgb, Tensor(), Tensor());
  const render::Kept& k = cache.kept;
  if (k.count > 0) {
    Tensor dvals = render::gather_rows(cg.dvalues, k.index, k.count);
    grads.head = field::appearance_backward(m.head, cache.head, dvals);
    field::features_backward(m.app, cache.kept_pos, grads.head.dfeat, grads.app);
  } else {
    grads.head = zero_head_grads(m);
  }
  field::density_backward(m.density, s.positions, cache.sigma, cg.dsigma, grads.density, m.cfg.act);
}

ViewRender render_camera(const DensityModel& m, const scene::Scene& scene, const scene::Camera& cam, int chunk) {
  const scene::Rays rays = scene::camera_rays(scene, cam);
  const int64_t n = static_cast<int64_t>(rays.size());
  ViewRender v;
  v.width = cam.width;
  v.height = cam.height;
  v.rgb.resize(size_t(n) * 3);
  v.acc.resize(size_t(n));
  v.depth.resize(size_t(n));
  for (int64_t b = 0; b < n; b += chunk) {
    const int64_t R = std::min<int64_t>(chunk, n - b);
    std::vector<float> o(rays.origins.begin() + 3 * b, rays.origins.begin() + 3 * (b + R));
    std::vector<float> d(rays.directions.begin() + 3 * b, rays.directions.begin() + 3 * (b + R));
    RayOutputs out = render_rays(m, Tensor::from_host(o, {R, 3}, "render origins"),
                                 Tensor::from_host(d, {R, 3}, "render directions"), false, 0, nullptr);
    const auto rgb = out.rgb.to_host(), acc = out.acc.to_host(), depth = out.depth.to_host();
    std::copy(rgb.begin(), rgb.end(), v.rgb.begin() + 3 * b);
    for (int64_t i = 0; i < R; ++i) {
      v.acc[size_t(b + i)] = acc[size_t(i)];
      v.depth[size_t(b + i)] = acc[size_t(i)] > 1e-6f ? depth[size_t(i)] / acc[size_t(i)] : 0.0f;
    }
  }
  return v;
}

// ---- checkpoints -------------------------------------------------------------------------------------------
// The alpha mask is stored packed, 8 voxels per value (0..255), as TensoRF packs its mask bits: it is
// a record of the mask training used, not something to recompute from a later grid.
static io::HostTensor pack_mask(const field::AlphaMask& m) {
  const auto v = m.to_host();
  io::HostTensor t;
  t.data.assign((v.size() + 7) / 8, 0.0f);
  for (size_t i = 0; i < v.size(); ++i)
    if (v[i]) t.data[i / 8] += float(1 << (i % 8));
  t.shape = {int64_t(t.data.size())};
  return t;
}

static field::AlphaMask unpack_mask(const io::HostTensor& t, std::array<int, 3> res, const std::string& path) {
  field::AlphaMask m;
  m.res = res;
  const size_t n = size_t(res[0]) * res[1] * res[2];
  if (t.data.size() != (n + 7) / 8)
    throw Error("checkpoint " + path + ": alpha mask has " + std::to_string(t.data.size()) + " packed values, " +
                std::to_string((n + 7) / 8) + " expected");
  std::vector<uint8_t> v(n);
  int lo[3] = {res[0], res[1], res[2]}, hi[3] = {-1, -1, -1};
  for (size_t i = 0; i < n; ++i) {
    const int byte = static_cast<int>(t.data[i / 8]);
    v[i] = (byte >> (i % 8)) & 1;
    if (v[i]) {
      ++m.occupied;
      const int c[3] = {int(i % res[0]), int(i / res[0] % res[1]), int(i / (size_t(res[0]) * res[1]))};
      for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], c[a]), hi[a] = std::max(hi[a], c[a]);
    }
  }
  if (m.occupied)
    for (int a = 0; a < 3; ++a) {
      m.lo[a] = -1.0f + 2.0f * lo[a] / res[a];
      m.hi[a] = -1.0f + 2.0f * (hi[a] + 1) / res[a];
    }
  m.voxels = std::make_shared<host::Buffer>(n, "alpha mask");
  host::check(clEnqueueWriteBuffer(host::Runtime::instance().queue(), m.voxels->mem(), CL_TRUE, 0, n, v.data(), 0,
                                   nullptr, nullptr),
              "clEnqueueWriteBuffer", "alpha mask from " + path);
  return m;
}

static const char* kHeadNames[] = {"basis", "w1", "b1", "w2", "b2", "w3", "b3"};

void save_model(io::Checkpoint& ck, const DensityModel& m) {
  json j;
  j["config"] = m.cfg.to_json();
  j["res"] = m.res();
  j["box_lo"] = m.box_lo;
  j["box_hi"] = m.box_hi;
  j["near"] = m.near;
  j["far"] = m.far;
  j["ndc"] = m.ndc;
  j["has_background"] = m.has_background;
  j["background"] = m.background;
  j["mask_res"] = m.mask.voxels ? m.mask.res : std::array<int, 3>{0, 0, 0};
  ck.meta["model"] = j;
  ck.put("model.density", m.density.params);
  ck.put("model.app", m.app.params);
  auto& h = const_cast<field::AppearanceHead&>(m.head);
  auto ps = h.params();
  for (size_t i = 0; i < ps.size(); ++i) ck.put(std::string("model.head.") + kHeadNames[i], *ps[i]);
  if (m.mask.voxels) ck.tensors["model.mask"] = pack_mask(m.mask);
}

DensityModel load_model(const io::Checkpoint& ck) {
  if (!ck.meta.contains("model")) throw Error("checkpoint " + ck.path + " has no model section");
  DensityModel m;
  try {
    const json& j = ck.meta.at("model");
    m.cfg = DensityModelConfig::from_json(j.at("config"));
    const auto res = j.at("res").get<std::array<int, 3>>();
    m.box_lo = j.at("box_lo").get<std::array<float, 3>>();
    m.box_hi = j.at("box_hi").get<std::array<float, 3>>();
    m.near = j.at("near").get<float>();
    m.far = j.at("far").get<float>();
    m.ndc = j.at("ndc").get<bool>();
    m.has_background = j.at("has_background").get<bool>();
    m.background = j.at("background").get<std::array<float, 3>>();
    const auto mask_res = j.at("mask_res").get<std::array<int, 3>>();
    const int64_t nd = field::VMGrid::numel_of(res, m.cfg.density_rank);
    const int64_t na = field::VMGrid::numel_of(res, m.cfg.app_rank);
    m.density = field::VMGrid::from_params(res, m.cfg.density_rank, ck.device("model.density", {nd}));
    m.app = field::VMGrid::from_params(res, m.cfg.app_rank, ck.device("model.app", {na}));
    m.head = field::AppearanceHead::create(head_config(m.cfg), 0);
    auto ps = m.head.params();
    for (size_t i = 0; i < ps.size(); ++i)
      *ps[i] = ck.device(std::string("model.head.") + kHeadNames[i], ps[i]->shape());
    if (mask_res[0] > 0) m.mask = unpack_mask(ck.get("model.mask"), mask_res, ck.path);
  } catch (const json::exception& e) {
    throw Error("checkpoint " + ck.path + ": bad model metadata (" + e.what() + ")");
  }
  m.update_step();
  return m;
}

std::vector<NamedParam> named_params(DensityModel& m) {
  std::vector<NamedParam> out{{"density", &m.density.params, 0}, {"app", &m.app.params, 0}};
  auto ps = m.head.params();
  for (size_t i = 0; i < ps.size(); ++i) out.push_back({std::string("head.") + kHeadNames[i], ps[i], 1});
  return out;
}

std::vector<Tensor*> grad_list(DensityGrads& g) {
  std::vector<Tensor*> out{&g.density, &g.app};
  for (Tensor* t : g.head.params()) out.push_back(t);
  return out;
}

}  // namespace stylerf::train
