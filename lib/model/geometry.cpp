#include "lib/model/geometry.hpp"

#include <cmath>
#include <sstream>

#include "host/error.hpp"
#include "lib/io/checkpoint.hpp"

namespace stylerf::model {

using host::Error;
using nlohmann::json;

std::array<float, 3> Geometry::box_size() const {
  return {box_hi[0] - box_lo[0], box_hi[1] - box_lo[1], box_hi[2] - box_lo[2]};
}

void Geometry::update_step() {
  const auto r = res();
  mask_step = render::step_for_grid(box_lo, box_hi, r, step_ratio);
  if (ndc) {
    // TensoRF's NDC sampling: N = |res| / step_ratio samples evenly over [near, far] of the NDC parameter.
    const double n = std::sqrt(double(r[0]) * r[0] + double(r[1]) * r[1] + double(r[2]) * r[2]) / step_ratio;
    step = static_cast<float>((far - near) / n);
    max_samples = static_cast<int>(n) + 1;
  } else {
    step = mask_step;
    max_samples = render::max_samples_for_grid(box_lo, box_hi, step);
  }
}

Geometry Geometry::with_step_ratio(float ratio) const {
  if (!(ratio > 0.0f) || !std::isfinite(ratio))
    throw host::Error("geometry: the step ratio must be positive, got " + std::to_string(ratio));
  Geometry g = *this;
  g.step_ratio = ratio;
  g.update_step();
  g.mask_step = mask_step;
  return g;
}

render::MarchConfig Geometry::march_config(bool jitter, uint32_t seed, uint32_t ray_base) const {
  render::MarchConfig mc;
  mc.box_lo = box_lo;
  mc.box_hi = box_hi;
  mc.near = near;
  mc.far = far;
  mc.step = step;
  mc.max_samples = max_samples;
  mc.jitter = jitter;
  mc.seed = seed;
  mc.ray_base = ray_base;
  mc.delta_scale = distance_scale;
  return mc;
}

json BackgroundShell::to_json() const { return json{{"radius", radius}, {"height", height}, {"width", width}}; }

BackgroundShell BackgroundShell::from_json(const json& j, const std::string& where) {
  BackgroundShell b;
  b.radius = j.at("radius").get<float>();
  b.height = j.at("height").get<int>();
  b.width = j.at("width").get<int>();
  if (!(b.radius > 0) || !std::isfinite(b.radius) || b.height < 1 || b.width < 1)
    throw Error(where + ": bad background shell (radius " + std::to_string(b.radius) + ", map " + std::to_string(b.width) +
                "x" + std::to_string(b.height) + ")");
  return b;
}

render::ShellTaps Geometry::shell_taps(const Tensor& origins, const Tensor& dirs) const {
  if (!shell.on()) throw Error("shell_taps: this geometry has no background shell");
  return render::background_shell_taps(origins, dirs, shell.radius, shell.height, shell.width);
}

Tensor Geometry::background_tensor() const {
  if (!has_background) return Tensor();
  return Tensor::from_host({background[0], background[1], background[2]}, {3}, "background colour");
}

std::string Geometry::describe() const {
  std::ostringstream o;
  const auto r = res();
  o << "grid " << r[0] << "x" << r[1] << "x" << r[2] << ", density rank " << density.rank[0] << "/"
    << density.rank[1] << "/" << density.rank[2] << ", step " << step << " (<= " << max_samples
    << " samples/ray), box [" << box_lo[0] << ", " << box_lo[1] << ", " << box_lo[2] << "] .. [" << box_hi[0] << ", "
    << box_hi[1] << ", " << box_hi[2] << "]";
  if (mask.voxels.defined())
    o << ", alpha mask " << mask.res[0] << "x" << mask.res[1] << "x" << mask.res[2] << " ("
      << 100.0 * double(mask.occupied) / (double(mask.res[0]) * mask.res[1] * mask.res[2]) << "% occupied"
      << (use_mask ? "" : ", not used") << ")";
  return o.str();
}

// ---- checkpoints ---------------------------------------------------------------------------------------
io::HostTensor pack_mask(const field::AlphaMask& m) {
  const auto v = m.to_host();
  io::HostTensor t;
  t.data.assign((v.size() + 7) / 8, 0.0f);
  for (size_t i = 0; i < v.size(); ++i)
    if (v[i]) t.data[i / 8] += float(1 << (i % 8));
  t.shape = {int64_t(t.data.size())};
  return t;
}

field::AlphaMask unpack_mask(const io::HostTensor& t, std::array<int, 3> res, const std::string& path) {
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
  m.voxels = Tensor::from_host(v, {res[2], res[1], res[0]}, "alpha mask from " + path);
  return m;
}

void Geometry::save(io::Checkpoint& ck, const std::string& prefix) const {
  json j;
  j["res"] = res();
  j["density_rank"] = density.rank;
  j["activation"] = act == field::DensityActivation::Relu ? "relu" : "softplus";
  j["box_lo"] = box_lo;
  j["box_hi"] = box_hi;
  j["near"] = near;
  j["far"] = far;
  j["ndc"] = ndc;
  j["has_background"] = has_background;
  j["background"] = background;
  if (shell.on()) j["shell"] = shell.to_json();
  j["step_ratio"] = step_ratio;
  j["distance_scale"] = distance_scale;
  j["weight_threshold"] = weight_threshold;
  j["mask_res"] = mask.voxels.defined() ? mask.res : std::array<int, 3>{0, 0, 0};
  ck.meta[prefix + "geometry"] = j;
  ck.put(prefix + "density", density.params);
  if (mask.voxels.defined()) ck.tensors[prefix + "mask"] = pack_mask(mask);
}

Geometry Geometry::load(const io::Checkpoint& ck, const std::string& prefix) {
  const std::string key = prefix + "geometry";
  if (!ck.meta.contains(key)) throw Error("checkpoint " + ck.path + " has no geometry (" + key + ")");
  Geometry g;
  try {
    const json& j = ck.meta.at(key);
    const auto res = j.at("res").get<std::array<int, 3>>();
    const auto rank = j.at("density_rank").get<std::array<int, 3>>();
    g.act = field::parse_density_activation(j.at("activation").get<std::string>());
    g.box_lo = j.at("box_lo").get<std::array<float, 3>>();
    g.box_hi = j.at("box_hi").get<std::array<float, 3>>();
    g.near = j.at("near").get<float>();
    g.far = j.at("far").get<float>();
    g.ndc = j.at("ndc").get<bool>();
    g.ert_threshold = Geometry::default_ert_threshold(g.ndc);
    g.has_background = j.at("has_background").get<bool>();
    g.background = j.at("background").get<std::array<float, 3>>();
    if (j.contains("shell")) g.shell = BackgroundShell::from_json(j.at("shell"), "checkpoint " + ck.path);
    g.step_ratio = j.at("step_ratio").get<float>();
    g.distance_scale = j.at("distance_scale").get<float>();
    g.weight_threshold = j.at("weight_threshold").get<float>();
    const auto mask_res = j.at("mask_res").get<std::array<int, 3>>();
    g.density = field::VMGrid::from_params(res, rank,
                                           ck.device(prefix + "density", {field::VMGrid::numel_of(res, rank)}));
    if (mask_res[0] > 0) g.mask = unpack_mask(ck.get(prefix + "mask"), mask_res, ck.path);
  } catch (const json::exception& e) {
    throw Error("checkpoint " + ck.path + ": bad geometry metadata (" + e.what() + ")");
  }
  g.update_step();
  return g;
}

}  // namespace stylerf::model
