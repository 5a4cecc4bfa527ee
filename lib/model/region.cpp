#include "lib/model/region.hpp"

#include <cmath>
#include <sstream>

#include "host/error.hpp"
#include "host/launch.hpp"

namespace stylerf::model {

using host::Error;

namespace {
std::vector<double> parse_numbers(const std::string& list, const std::string& spec) {
  std::vector<double> v;
  std::stringstream ss(list);
  std::string item;
  while (std::getline(ss, item, ',')) {
    size_t used = 0;
    double x = 0;
    try {
      x = std::stod(item, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != item.size() || std::isnan(x))
      throw host::SettingError("region", spec + ": '" + item + "' is not a number");
    v.push_back(x);
  }
  return v;
}
void need_finite(const std::vector<double>& v, size_t count, const std::string& spec) {
  for (size_t i = 0; i < count; ++i)
    if (!std::isfinite(v[i])) throw host::SettingError("region", spec + ": every coordinate must be finite");
}
}  // namespace

Region Region::parse(const std::string& spec, const std::vector<scene::Camera>& path) {
  const auto colon = spec.find(':');
  if (colon == std::string::npos)
    throw host::SettingError("region", "'" + spec + "': expected box:x0,y0,z0,x1,y1,z1, sphere:x,y,z,r or depth:d0,d1");
  const std::string kind = spec.substr(0, colon);
  const std::vector<double> v = parse_numbers(spec.substr(colon + 1), spec);
  Region r;
  r.spec = spec;
  if (kind == "box") {
    if (v.size() != 6) throw host::SettingError("region", spec + ": a box takes 6 numbers (x0,y0,z0,x1,y1,z1)");
    need_finite(v, 6, spec);
    for (int a = 0; a < 3; ++a)
      if (!(v[a] < v[3 + a])) throw host::SettingError("region", spec + ": each lower corner must be below the upper one");
    r.kind = Box;
  } else if (kind == "sphere") {
    if (v.size() != 4) throw host::SettingError("region", spec + ": a sphere takes 4 numbers (x,y,z,r)");
    need_finite(v, 4, spec);
    if (!(v[3] > 0)) throw host::SettingError("region", spec + ": the radius must be > 0");
    r.kind = Sphere;
  } else if (kind == "depth") {
    if (v.size() != 2) throw host::SettingError("region", spec + ": a depth interval takes 2 numbers (d0,d1)");
    if (!std::isfinite(v[0]) || !(v[0] < v[1])) throw host::SettingError("region", spec + ": needs a finite d0 < d1");
    if (path.empty()) throw host::SettingError("region", spec + ": a depth interval needs a camera path");
    std::array<double, 3> c{}, a{};
    for (const auto& cam : path)
      for (int k = 0; k < 3; ++k) c[k] += cam.position()[k] / path.size(), a[k] += cam.forward()[k];
    const double n = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
    if (!(n > 1e-6)) throw host::SettingError("region", spec + ": the cameras look in no common direction; use box: or sphere:");
    r.kind = Slab;
    r.p = {float(c[0]), float(c[1]), float(c[2]), float(a[0] / n), float(a[1] / n), float(a[2] / n), float(v[0]),
           float(v[1])};
    return r;
  } else {
    throw host::SettingError("region", "'" + spec + "': unknown kind '" + kind + "' (box, sphere or depth)");
  }
  for (size_t i = 0; i < v.size(); ++i) r.p[i] = float(v[i]);
  return r;
}

bool Region::contains(const std::array<double, 3>& w) const {
  switch (kind) {
    case Box:
      return w[0] >= p[0] && w[1] >= p[1] && w[2] >= p[2] && w[0] <= p[3] && w[1] <= p[4] && w[2] <= p[5];
    case Sphere: {
      const double dx = w[0] - p[0], dy = w[1] - p[1], dz = w[2] - p[2];
      return dx * dx + dy * dy + dz * dz <= double(p[3]) * p[3];
    }
    case Slab: {
      const double t = (w[0] - p[0]) * p[3] + (w[1] - p[1]) * p[4] + (w[2] - p[2]) * p[5];
      return t >= p[6] && t <= p[7];
    }
  }
  return false;
}

RegionSpace RegionSpace::of(const Geometry& g, const scene::Scene& scene) {
  RegionSpace s;
  s.lo = g.box_lo;
  s.hi = g.box_hi;
  s.ndc = g.ndc;
  if (s.ndc) {
    if (scene.train.empty() && scene.test.empty()) throw Error("region: an NDC scene without cameras");
    const scene::Camera& c = scene.train.empty() ? scene.test[0].camera : scene.train[0].camera;
    s.sx = float(c.width / (2.0 * c.fx));
    s.sy = float(c.height / (2.0 * c.fy));
    s.near = scene.ndc_near;
  }
  return s;
}

std::array<double, 3> RegionSpace::world(const std::array<double, 3>& pos) const {
  std::array<double, 3> p{};
  for (int a = 0; a < 3; ++a) p[a] = lo[a] + 0.5 * (pos[a] + 1.0) * (double(hi[a]) - lo[a]);
  if (!ndc) return p;
  const double z = 2.0 * near / (p[2] - 1.0);
  return {-p[0] * z * sx, -p[1] * z * sy, z};
}

bool RegionSpace::at_infinity(const std::array<double, 3>& pos) const {
  return ndc && lo[2] + 0.5 * (pos[2] + 1.0) * (double(hi[2]) - lo[2]) >= 1.0;
}

bool RegionSpace::contains(const Region& r, const std::array<double, 3>& pos) const {
  if (at_infinity(pos)) return r.kind == Region::Slab && std::isinf(r.p[7]) && r.p[7] > 0;
  return r.contains(world(pos));
}

host::Tensor region_indicator(const host::Tensor& pos, const Region& region, const RegionSpace& space) {
  if (pos.ndim() != 2 || pos.dim(1) != 3) throw Error("region_indicator: positions must be [K, 3]");
  const int64_t K = pos.dim(0);
  host::Tensor out = host::Tensor::zeros({K}, "region indicator");
  if (K == 0) return out;
  const host::Tensor geo = host::Tensor::from_host(
      {space.lo[0], space.lo[1], space.lo[2], space.hi[0], space.hi[1], space.hi[2], space.sx, space.sy, space.near},
      {9}, "region space");
  const host::Tensor params =
      host::Tensor::from_host(std::vector<float>(region.p.begin(), region.p.end()), {8}, "region parameters");
  host::launch("region", "region_indicator", {size_t(K)}, pos, out, int(K), geo, int(space.ndc), int(region.kind),
               params);
  return out;
}

Tensor RegionHead::forward(const Tensor& pos, const Tensor&, std::unique_ptr<Context>* ctx) const {
  if (ctx) throw Error("region head: inference only (the indicator has no gradient)");
  return region_indicator(pos, region_, space_).reshape({pos.dim(0), 1});
}

void RegionHead::backward(const Context&, const Tensor&) {
  throw Error("region head: inference only (the indicator has no gradient)");
}

}  // namespace stylerf::model
