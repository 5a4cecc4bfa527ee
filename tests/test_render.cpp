// Ray marching and compositing (kernels/render.cl via lib/render/): sample lists against a CPU reference,
// compositing forward against a double reference and backward against its finite differences, and the
// hard cases: sigma = 0 everywhere, sigma = 1e6 at the first sample, delta = 0, huge sigma, a ray that
// misses the box, an empty ray list, NDC-like rays starting at the near plane (near = 0). The distortion
// term on the weights likewise: a double reference written as the double sum, central differences, and
// rays without samples, with one sample, with all their weight in one sample or none.
#include <doctest/doctest.h>

#include <cfloat>
#include <cmath>
#include <cstring>
#include <vector>

#include "host/error.hpp"
#include "host/runtime.hpp"
#include "host/tensor.hpp"
#include "lib/field/alpha_mask.hpp"
#include "lib/render/composite.hpp"
#include "lib/render/composite_values.hpp"
#include "lib/render/distortion.hpp"
#include "lib/render/weights.hpp"
#include "lib/render/ray_march.hpp"
#include "lib/render/scan.hpp"
#include "lib/render/step_merge.hpp"
#include "tests/testing.hpp"

using namespace stylerf;
using host::Tensor;
using render::MarchConfig;
using render::Samples;
using testing::check_close;

namespace {

// ---- ray-marching reference (double; the jitter hash is integer and identical) -------------------------
float hash_uniform(uint32_t seed, uint32_t i) {
  uint32_t h = (i * 0x9E3779B9u) ^ seed;
  h ^= h >> 16;
  h *= 0x7feb352du;
  h ^= h >> 15;
  h *= 0x846ca68bu;
  h ^= h >> 16;
  return float(h >> 8) * (1.0f / 16777216.0f);
}

struct RefSample {
  double t, q[3];
};

// Samples of one ray; `ambiguous` is set when a float implementation could legitimately decide a sample
// differently (count boundary or mask voxel boundary within 1e-4; float error is ~1e-6).
std::vector<RefSample> ref_march(const float* o, const float* d, int r, const MarchConfig& c,
                                 const std::vector<uint8_t>* mask, const std::array<int, 3>& mr, bool& ambiguous) {
  ambiguous = false;
  double tmin = c.near, tmax = c.far;
  for (int a = 0; a < 3; ++a) {
    if (d[a] == 0.0f) {
      if (o[a] < c.box_lo[a] || o[a] > c.box_hi[a]) return {};
    } else {
      const double t1 = (c.box_lo[a] - double(o[a])) / d[a], t2 = (c.box_hi[a] - double(o[a])) / d[a];
      tmin = std::max(tmin, std::min(t1, t2));
      tmax = std::min(tmax, std::max(t1, t2));
    }
  }
  if (!(tmax >= tmin)) return {};
  const double jitter = c.jitter ? hash_uniform(c.seed, c.ray_base + uint32_t(r)) : 0.0;
  const double span = (tmax - tmin) / c.step - jitter;
  if (span < 0) return {};
  if (std::fabs(span - std::round(span)) < 1e-4) ambiguous = true;
  const int n = int(std::min(std::floor(span) + 1.0, double(c.max_samples)));
  std::vector<RefSample> out;
  for (int i = 0; i < n; ++i) {
    RefSample s;
    s.t = tmin + c.step * (i + jitter);
    bool occ = true;
    int v[3];
    for (int a = 0; a < 3; ++a) {
      const double p = o[a] + s.t * d[a];
      s.q[a] = std::min(1.0, std::max(-1.0, (p - c.box_lo[a]) / (c.box_hi[a] - c.box_lo[a]) * 2 - 1));
      if (mask) {
        const double f = (s.q[a] + 1) * 0.5 * mr[a];
        if (std::fabs(f - std::round(f)) < 1e-4 && std::round(f) > 0 && std::round(f) < mr[a]) ambiguous = true;
        v[a] = std::min(std::max(int(std::floor(f)), 0), mr[a] - 1);
      }
    }
    if (mask) occ = (*mask)[(size_t(v[2]) * mr[1] + v[1]) * mr[0] + v[0]] != 0;
    if (occ) out.push_back(s);
  }
  return out;
}

field::AlphaMask mask_from_host(const std::vector<uint8_t>& v, std::array<int, 3> res) {
  field::AlphaMask m;
  m.res = res;
  m.voxels = Tensor::from_host(v, {res[2], res[1], res[0]}, "test mask");
  for (auto b : v) m.occupied += b;
  return m;
}

// An I32 tensor [n] of host ints.
Tensor i32(const std::vector<int32_t>& v, const std::string& what = "test int list") {
  return Tensor::from_host(v, {int64_t(v.size())}, what);
}

// Random rays: origins on a sphere of radius 3 aimed near the box centre (some miss), plus rays starting
// inside, rays parallel to axes (inside and outside the slab), and one pointing away.
void make_rays(int n, uint64_t seed, std::vector<float>& o, std::vector<float>& d) {
  auto u = testing::random_uniform(size_t(6) * n, seed, -1.0f, 1.0f);
  for (int i = 0; i < n; ++i) {
    float oo[3] = {u[6 * i] * 3, u[6 * i + 1] * 3, u[6 * i + 2] * 3};
    float len = std::sqrt(oo[0] * oo[0] + oo[1] * oo[1] + oo[2] * oo[2]) + 1e-6f;
    if (i % 5 == 0) for (auto& x : oo) x /= len;  // inside the box
    float tgt[3] = {u[6 * i + 3] * 1.5f, u[6 * i + 4] * 1.5f, u[6 * i + 5] * 1.5f};
    float dd[3] = {tgt[0] - oo[0], tgt[1] - oo[1], tgt[2] - oo[2]};
    float dl = std::sqrt(dd[0] * dd[0] + dd[1] * dd[1] + dd[2] * dd[2]);
    for (int a = 0; a < 3; ++a) {
      o.push_back(oo[a]);
      d.push_back(dd[a] / dl);
    }
  }
  const float extra[][6] = {{-3, 0.2f, 0.3f, 1, 0, 0},   {-3, 2.0f, 0.3f, 1, 0, 0},  {0.1f, 0.2f, -5, 0, 0, 1},
                            {0, 0, 0, 0, 1, 0},          {3, 3, 3, 1, 1, 1},         {-3, -1.0f, 0.0f, 1, 0, 0}};
  for (auto& e : extra) {
    float l = std::sqrt(e[3] * e[3] + e[4] * e[4] + e[5] * e[5]);
    o.insert(o.end(), {e[0], e[1], e[2]});
    d.insert(d.end(), {e[3] / l, e[4] / l, e[5] / l});
  }
}

void check_march(const Samples& s, const std::vector<float>& o, const std::vector<float>& d, const MarchConfig& c,
                 const std::vector<uint8_t>* mask, const std::array<int, 3>& mr) {
  const int R = int(o.size() / 3);
  const auto counts = s.ray_count.to_host_i32(), offs = s.ray_offset.to_host_i32();
  const auto ridx = s.ray_index.to_host_i32();
  const auto pos = s.positions.to_host(), tv = s.t.to_host(), dl = s.deltas.to_host();
  REQUIRE(int(counts.size()) == R);
  int ambiguous = 0, hits = 0;
  int64_t total = 0;
  for (int r = 0; r < R; ++r) {
    CHECK(offs[r] == total);  // exclusive prefix sum
    total += counts[r];
    bool amb;
    const auto want = ref_march(&o[3 * r], &d[3 * r], r, c, mask, mr, amb);
    if (amb) {
      ++ambiguous;
      continue;
    }
    hits += !want.empty();
    REQUIRE_MESSAGE(counts[r] == int(want.size()), "ray " << r);
    for (int k = 0; k < counts[r]; ++k) {
      const int j = offs[r] + k;
      CHECK(ridx[j] == r);
      // Positions and t in float against double: atol 1e-4 (|t| <= ~10, float epsilon 1e-7 * a few ops).
      CHECK(std::fabs(tv[j] - want[k].t) < 1e-4 * (1 + std::fabs(want[k].t)));
      for (int a = 0; a < 3; ++a) CHECK(std::fabs(pos[3 * j + a] - want[k].q[a]) < 1e-4);
      const double len = std::sqrt(d[3 * r] * d[3 * r] + d[3 * r + 1] * d[3 * r + 1] + d[3 * r + 2] * d[3 * r + 2]);
      CHECK(std::fabs(dl[j] - c.step * len * c.delta_scale) < 1e-6);
    }
  }
  CHECK(total == s.count);
  CHECK(ambiguous < R / 10 + 1);
  CHECK(hits > R / 3);  // most rays hit: the comparison covers real samples
}

}  // namespace

TEST_CASE("ray marching matches the CPU reference: counts, offsets, positions, t, deltas (no mask, jitter)") {
  std::vector<float> o, d;
  make_rays(300, 1, o, d);
  const int R = int(o.size() / 3);
  Tensor to = Tensor::from_host(o, {R, 3}), td = Tensor::from_host(d, {R, 3});
  MarchConfig c;
  c.box_lo = {-1.0f, -0.8f, -1.2f};
  c.box_hi = {1.0f, 0.9f, 1.1f};
  c.near = 0.1f;
  c.far = 6.0f;
  c.step = render::step_for_grid(c.box_lo, c.box_hi, {32, 30, 34});
  c.max_samples = render::max_samples_for_grid(c.box_lo, c.box_hi, c.step);
  c.delta_scale = 2.0f;
  for (bool jitter : {false, true}) {
    c.jitter = jitter;
    c.seed = 1234;
    check_march(render::march(to, td, c, nullptr), o, d, c, nullptr, {1, 1, 1});
  }
  // The cap: at most max_samples per ray.
  c.max_samples = 7;
  Samples s = render::march(to, td, c, nullptr);
  for (int n : s.ray_count.to_host_i32()) CHECK(n <= 7);
  check_march(s, o, d, c, nullptr, {1, 1, 1});
}

TEST_CASE("ray marching a slice of a batch from ray_base on draws the jitter the whole batch draws there") {
  std::vector<float> o, d;
  make_rays(300, 1, o, d);
  const int R = int(o.size() / 3), lo = R / 3;
  MarchConfig c;
  c.step = 0.05f;
  c.max_samples = 200;
  c.far = 6.0f;
  c.jitter = true;
  c.seed = 99;
  const Samples whole = render::march(Tensor::from_host(o, {R, 3}), Tensor::from_host(d, {R, 3}), c, nullptr);
  const std::vector<float> po(o.begin() + 3 * lo, o.end()), pd(d.begin() + 3 * lo, d.end());
  c.ray_base = uint32_t(lo);
  const Samples part = render::march(Tensor::from_host(po, {R - lo, 3}), Tensor::from_host(pd, {R - lo, 3}), c, nullptr);
  check_march(part, po, pd, c, nullptr, {1, 1, 1});  // the reference hashes ray_base + r too
  const auto wc = whole.ray_count.to_host_i32(), wo = whole.ray_offset.to_host_i32();
  const auto pc = part.ray_count.to_host_i32();
  const auto wt = whole.t.to_host(), pt = part.t.to_host();
  REQUIRE(part.count > 0);
  REQUIRE(size_t(whole.count - part.count) == size_t(wo[size_t(lo)]));
  for (int r = lo; r < R; ++r) REQUIRE(pc[size_t(r - lo)] == wc[size_t(r)]);
  for (size_t i = 0; i < pt.size(); ++i) REQUIRE(pt[i] == wt[size_t(wo[size_t(lo)]) + i]);
  // Without the base the slice's jitter is another draw.
  c.ray_base = 0;
  const auto other = render::march(Tensor::from_host(po, {R - lo, 3}), Tensor::from_host(pd, {R - lo, 3}), c, nullptr).t.to_host();
  CHECK(other != pt);
}

TEST_CASE("ray marching skips empty alpha-mask voxels exactly like the reference") {
  std::vector<float> o, d;
  make_rays(300, 2, o, d);
  const int R = int(o.size() / 3);
  Tensor to = Tensor::from_host(o, {R, 3}), td = Tensor::from_host(d, {R, 3});
  const std::array<int, 3> mr{5, 6, 7};
  std::vector<uint8_t> mv(size_t(mr[0]) * mr[1] * mr[2]);
  auto u = testing::random_uniform(mv.size(), 3, 0.0f, 1.0f);
  for (size_t i = 0; i < mv.size(); ++i) mv[i] = u[i] < 0.4f;
  field::AlphaMask m = mask_from_host(mv, mr);
  MarchConfig c;
  c.near = 0.0f;
  c.far = 10.0f;
  c.step = 0.05f;
  c.jitter = true;
  c.seed = 99;
  Samples with = render::march(to, td, c, &m);
  check_march(with, o, d, c, &mv, mr);
  Samples without = render::march(to, td, c, nullptr);
  CHECK(with.count < without.count);  // the mask removed samples
  CHECK(with.count > 0);
}

TEST_CASE("ray marching hard cases: a ray that misses, an empty ray list, NDC-like rays from the near plane") {
  MarchConfig c;
  c.step = 0.1f;
  // A ray that misses: zero samples.
  {
    std::vector<float> o = {-3, 2.5f, 0}, d = {1, 0, 0};
    Samples s = render::march(Tensor::from_host(o, {1, 3}), Tensor::from_host(d, {1, 3}), c, nullptr);
    CHECK(s.count == 0);
    CHECK(s.ray_count.to_host_i32()[0] == 0);
  }
  // No rays at all.
  {
    Samples s = render::march(Tensor({0, 3}), Tensor({0, 3}), c, nullptr);
    CHECK(s.count == 0);
    CHECK(s.positions.numel() == 0);
  }
  // NDC-like: origins on the near plane z = -1 of the NDC box, near = 0, far = 1, d.z = 2 (z: -1 -> 1).
  {
    MarchConfig n;
    n.box_lo = {-1.5f, -1.67f, -1.0f};
    n.box_hi = {1.5f, 1.67f, 1.0f};
    n.near = 0.0f;
    n.far = 1.0f;
    n.step = 1.0f / 128;
    n.max_samples = 1000;
    std::vector<float> o = {0.3f, -0.2f, -1.0f, -1.4f, 1.6f, -1.0f}, d = {0.1f, 0.05f, 2.0f, 0.0f, 0.0f, 2.0f};
    Samples s = render::march(Tensor::from_host(o, {2, 3}), Tensor::from_host(d, {2, 3}), n, nullptr);
    const auto cnt = s.ray_count.to_host_i32();
    CHECK(cnt[0] == 129);  // t = 0, 1/128, ..., 1
    CHECK(cnt[1] == 129);
    const auto t = s.t.to_host(), p = s.positions.to_host();
    CHECK(t[0] == 0.0f);
    CHECK(p[2] == -1.0f);  // the first sample sits on the near plane
    CHECK(testing::all_finite(p));
  }
}

// ---- compositing reference -------------------------------------------------------------------------------
namespace {
struct RefComp {
  std::vector<double> val, acc, depth, w;
};
RefComp ref_composite(const std::vector<double>& sigma, const std::vector<double>& vals, const std::vector<float>& delta,
                      const std::vector<float>& t, const std::vector<int>& off, const std::vector<int>& cnt, int C,
                      const std::vector<float>* bg) {
  const int R = int(off.size());
  RefComp r;
  r.val.assign(size_t(R) * C, 0.0);
  r.acc.assign(R, 0.0);
  r.depth.assign(R, 0.0);
  r.w.assign(sigma.size(), 0.0);
  for (int i = 0; i < R; ++i) {
    double T = 1.0;
    for (int k = off[i]; k < off[i] + cnt[i]; ++k) {
      const double x = delta[k] > 0 ? std::max(sigma[k] * delta[k], 0.0) : 0.0;
      const double w = T * -std::expm1(-x);
      T *= std::exp(-x);
      r.w[k] = w;
      r.acc[i] += w;
      r.depth[i] += w * t[k];
      for (int c = 0; c < C; ++c) r.val[size_t(i) * C + c] += w * vals[size_t(k) * C + c];
    }
    if (bg)
      for (int c = 0; c < C; ++c) r.val[size_t(i) * C + c] += (1 - r.acc[i]) * (*bg)[c];
  }
  return r;
}

// A sample list for compositing tests without marching: R rays with the given counts.
Samples make_samples(const std::vector<int>& counts, const std::vector<float>& t, const std::vector<float>& delta) {
  Samples s;
  std::vector<int32_t> off;
  s.count = render::exclusive_scan(counts, off);
  s.ray_count = i32(counts);
  s.ray_offset = i32(off);
  s.t = Tensor::from_host(t, {s.count});
  s.deltas = Tensor::from_host(delta, {s.count});
  return s;
}

// Compositing through the two ops (lib/render/weights.hpp, lib/render/composite_values.hpp) with every
// sample kept, plus the background: what the ray pipeline does, checked against ref_composite.
render::KeptLayout all_kept(const Samples& s, const std::vector<int>& counts) {
  render::KeptLayout l;
  l.count = s.count;
  l.ray_offset = s.ray_offset;
  l.ray_count = s.ray_count;
  std::vector<int32_t> ray;
  for (int r = 0; r < int(counts.size()); ++r)
    for (int k = 0; k < counts[r]; ++k) ray.push_back(r);
  l.ray_index = i32(ray);
  return l;
}
struct OpsComposite {
  Tensor value, acc, depth, weights;
};
OpsComposite composite_ops(const Samples& s, const std::vector<int>& counts, const Tensor& sigma, const Tensor& vals,
                           const Tensor& bg) {
  auto w = render::weights_forward(s, sigma);
  auto cv = render::composite_values_forward(all_kept(s, counts), w.w, vals);
  if (bg.defined()) render::background_forward(cv.value, w.acc, bg);
  return {cv.value, w.acc, w.depth, w.w};
}
struct OpsGrads {
  Tensor dsigma, dvalues;
};
OpsGrads composite_ops_backward(const Samples& s, const std::vector<int>& counts, const Tensor& sigma,
                                const Tensor& vals, const Tensor& bg, const Tensor& dval, const Tensor& dacc,
                                const Tensor& ddepth) {
  auto w = render::weights_forward(s, sigma);
  auto cg = render::composite_values_backward(all_kept(s, counts), w.w, vals, dval, Tensor());
  Tensor da = dacc.defined() ? dacc.clone() : Tensor();
  if (bg.defined() && dval.defined()) render::background_backward(dval, bg, da, da.defined());
  return {render::weights_backward(s, sigma, cg.dw, da, ddepth), cg.dvalues};
}
}  // namespace

TEST_CASE("compositing forward matches the double reference; backward matches its finite differences") {
  const std::vector<int> counts = {5, 0, 1, 12, 3};  // includes an empty ray
  int S = 0;
  for (int c : counts) S += c;
  std::vector<int32_t> off;
  render::exclusive_scan(counts, off);
  const int R = int(counts.size());
  for (int C : {3, 5}) {
    for (bool with_bg : {true, false}) {
      CAPTURE(C);
      CAPTURE(with_bg);
      auto sigma = testing::random_uniform(S, 1, 0.05f, 8.0f);
      auto vals = testing::random_uniform(size_t(S) * C, 2, 0.0f, 1.0f);
      auto delta = testing::random_uniform(S, 3, 0.01f, 0.2f);
      auto t = testing::random_uniform(S, 4, 0.5f, 4.0f);
      std::vector<float> bg = testing::random_uniform(C, 5, 0.0f, 1.0f);
      Samples s = make_samples(counts, t, delta);
      Tensor ts = Tensor::from_host(sigma, {S}), tv = Tensor::from_host(vals, {S, C});
      Tensor tbg = with_bg ? Tensor::from_host(bg, {C}) : Tensor();
      auto out = composite_ops(s, counts, ts, tv, tbg);
      auto ref = ref_composite(testing::to_double(sigma), testing::to_double(vals), delta, t, off, counts, C,
                               with_bg ? &bg : nullptr);
      // Products of <= 12 factors in float: rtol 1e-5, atol 1e-6.
      check_close(out.value.to_host(), ref.val, 1e-5, 1e-6, "value");
      check_close(out.acc.to_host(), ref.acc, 1e-5, 1e-6, "acc");
      check_close(out.depth.to_host(), ref.depth, 1e-5, 1e-6, "depth");
      check_close(out.weights.to_host(), ref.w, 1e-5, 1e-6, "weights");

      const auto gv = testing::to_double(testing::random_normal(size_t(R) * C, 6));
      const auto ga = testing::to_double(testing::random_normal(R, 7));
      const auto gd = testing::to_double(testing::random_normal(R, 8));
      auto loss = [&](const std::vector<double>& sg, const std::vector<double>& vl) {
        auto r = ref_composite(sg, vl, delta, t, off, counts, C, with_bg ? &bg : nullptr);
        return testing::dot(r.val, gv) + testing::dot(r.acc, ga) + testing::dot(r.depth, gd);
      };
      const auto sd = testing::to_double(sigma), vd = testing::to_double(vals);
      const auto fd_sigma = testing::finite_difference([&](const std::vector<double>& x) { return loss(x, vd); }, sd, 1e-6);
      const auto fd_vals = testing::finite_difference([&](const std::vector<double>& x) { return loss(sd, x); }, vd, 1e-6);
      auto g = composite_ops_backward(s, counts, ts, tv, tbg, Tensor::from_host(std::vector<float>(gv.begin(), gv.end()), {R, C}),
                                          Tensor::from_host(std::vector<float>(ga.begin(), ga.end()), {R}),
                                          Tensor::from_host(std::vector<float>(gd.begin(), gd.end()), {R}));
      // FD of a double function (h 1e-6: error ~1e-10); float kernel: rtol 1e-4, atol 1e-5.
      check_close(g.dsigma.to_host(), fd_sigma, 1e-4, 1e-5, "dsigma");
      check_close(g.dvalues.to_host(), fd_vals, 1e-4, 1e-5, "dvalues");
    }
  }
}

TEST_CASE("compositing hard cases: sigma 0, sigma 1e6 first, delta 0, huge sigma, missing ray, no rays") {
  const int C = 3;
  const std::vector<float> bg = {0.2f, 0.5f, 0.9f};
  Tensor tbg = Tensor::from_host(bg, {3});
  const std::vector<int> counts = {4, 0, 4, 4, 4};  // ray 1 missed the box
  const int S = 16, R = 5;
  std::vector<float> t(S), delta(S, 0.1f);
  for (int i = 0; i < S; ++i) t[i] = 1.0f + 0.1f * (i % 4);
  // ray 0: sigma 0 everywhere; ray 2: sigma 1e6 at the first sample; ray 3: large sigma with delta 0;
  // ray 4: FLT_MAX, 1e30 and inf (sigma * delta overflows to inf: exp(-inf) = 0, never inf * 0).
  std::vector<float> sigma(S, 0.0f);
  delta.assign(S, 0.1f);
  sigma[4] = 1e6f;  // ray 2, first sample
  sigma[5] = 3.0f;
  for (int i = 8; i < 12; ++i) {
    sigma[i] = 7.0f;
    delta[i] = 0.0f;
  }
  sigma[12] = 0.5f;
  sigma[13] = FLT_MAX;
  sigma[14] = 1e30f;
  sigma[15] = INFINITY;
  Samples s = make_samples(counts, t, delta);
  auto vals = testing::random_uniform(size_t(S) * C, 9, 0.0f, 1.0f);
  Tensor ts = Tensor::from_host(sigma, {S}), tv = Tensor::from_host(vals, {S, C});
  auto out = composite_ops(s, counts, ts, tv, tbg);
  const auto val = out.value.to_host(), acc = out.acc.to_host(), w = out.weights.to_host();
  CHECK(testing::all_finite(val));
  CHECK(testing::all_finite(acc));
  CHECK(testing::all_finite(w));
  CHECK(testing::all_finite(out.depth.to_host()));
  for (int r : {0, 1, 3}) {  // sigma 0 / no samples / delta 0: nothing absorbs, the background shows
    CHECK(acc[r] == 0.0f);
    for (int c = 0; c < 3; ++c) CHECK(val[3 * r + c] == bg[c]);
  }
  CHECK(w[4] == 1.0f);  // sigma 1e6 at the first sample: w_0 = 1 exactly, the rest 0
  for (int k = 5; k < 8; ++k) CHECK(w[k] == 0.0f);
  CHECK(acc[2] == 1.0f);
  for (int c = 0; c < 3; ++c) CHECK(val[6 + c] == doctest::Approx(vals[12 + c]).epsilon(1e-6));
  // Ray 4: the FLT_MAX sample absorbs everything left.
  CHECK(acc[4] == doctest::Approx(1.0f).epsilon(1e-6));
  CHECK(w[14] == 0.0f);
  CHECK(w[15] == 0.0f);

  auto ones = [](int n) { return Tensor::full({n}, 1.0f); };
  auto g = composite_ops_backward(s, counts, ts, tv, tbg, Tensor::full({R, C}, 1.0f), ones(R), ones(R));
  const auto ds = g.dsigma.to_host(), dv = g.dvalues.to_host();
  CHECK(testing::all_finite(ds));
  CHECK(testing::all_finite(dv));
  // sigma = 0 everywhere: dL/dsigma_k = delta_k * v_k with v_k = <1, c_k - bg> + 1 + t_k (T = 1, no later weight).
  for (int k = 0; k < 4; ++k) {
    double v = 1.0 + t[k];
    for (int c = 0; c < 3; ++c) v += vals[3 * k + c] - bg[c];
    CHECK(ds[k] == doctest::Approx(0.1 * v).epsilon(1e-5));
  }
  // sigma 1e6 first: nothing behind it matters, its own gradient is 0 (saturated), colour gradient = dvalue.
  for (int k = 4; k < 8; ++k) CHECK(ds[k] == 0.0f);
  for (int c = 0; c < 3; ++c) CHECK(dv[12 + c] == 1.0f);
  for (int k = 8; k < 12; ++k) CHECK(ds[k] == 0.0f);  // delta 0

  // No rays, no samples.
  Samples e = make_samples({}, {}, {});
  auto eo = composite_ops(e, {}, Tensor({0}), Tensor({0, 3}), tbg);
  CHECK(eo.value.numel() == 0);
  auto eg = composite_ops_backward(e, {}, Tensor({0}), Tensor({0, 3}), tbg, Tensor({0, 3}), Tensor(), Tensor());
  CHECK(eg.dsigma.numel() == 0);
}

TEST_CASE("dropping samples below a weight threshold keeps the rest in order; gather/scatter round trip") {
  const std::vector<int> counts = {6, 0, 3, 9};
  const int S = 18;
  auto w = testing::random_uniform(S, 11, 0.0f, 2e-4f);  // about half below 1e-4
  w[0] = 1e-4f;                                           // exactly at the threshold: kept
  std::vector<float> t(S), delta(S, 0.1f);
  for (int i = 0; i < S; ++i) t[i] = float(i);
  Samples s = make_samples(counts, t, delta);
  auto pos = testing::random_uniform(size_t(S) * 3, 12, -1.0f, 1.0f);
  s.positions = Tensor::from_host(pos, {S, 3});
  std::vector<int32_t> ridx;
  for (int r = 0; r < 4; ++r) ridx.insert(ridx.end(), counts[r], r);
  s.ray_index = i32(ridx);
  auto k = render::keep_by_weight(s, Tensor::from_host(w, {S}), 1e-4f);
  std::vector<int32_t> want;
  for (int i = 0; i < S; ++i)
    if (w[i] >= 1e-4f) want.push_back(i);
  REQUIRE(k.count == int64_t(want.size()));
  CHECK(want.size() > 3);
  CHECK(want.size() < size_t(S));
  CHECK(k.index.to_host_i32() == want);
  Samples c = render::compact(s, k);
  const auto cp = c.positions.to_host(), ct = c.t.to_host();
  const auto cr = c.ray_index.to_host_i32();
  for (size_t j = 0; j < want.size(); ++j) {
    CHECK(ct[j] == t[want[j]]);
    CHECK(cr[j] == ridx[want[j]]);
    for (int a = 0; a < 3; ++a) CHECK(cp[3 * j + a] == pos[3 * want[j] + a]);
  }
  // Per-ray counts of the compacted list sum to the kept count; offsets are their exclusive scan.
  const auto kc = c.ray_count.to_host_i32(), ko = c.ray_offset.to_host_i32();
  int64_t run = 0;
  for (size_t r = 0; r < kc.size(); ++r) {
    CHECK(ko[r] == run);
    run += kc[r];
  }
  CHECK(run == k.count);
  // scatter_rows puts kept rows back, zeros elsewhere.
  auto back = render::scatter_rows(c.positions, k.index, S).to_host();
  for (int i = 0; i < S; ++i) {
    const bool kept = w[i] >= 1e-4f;
    for (int a = 0; a < 3; ++a) CHECK(back[3 * i + a] == (kept ? pos[3 * i + a] : 0.0f));
  }
}

namespace {
// The kept list of the weighted-sum tests: five rays, one of them empty, one of one sample.
struct SumLayout {
  std::vector<int> counts = {3, 0, 1, 7, 2};
  int K = 0;
  std::vector<int32_t> off;
  render::KeptLayout layout;
};
SumLayout sum_layout() {
  SumLayout t;
  for (int c : t.counts) t.K += c;
  render::exclusive_scan(t.counts, t.off);
  t.layout = all_kept(make_samples(t.counts, std::vector<float>(t.K, 1.0f), std::vector<float>(t.K, 0.1f)), t.counts);
  return t;
}
}  // namespace

TEST_CASE("weighted sum over kept samples: every vector width, forward vs double reference, backward vs FD") {
  const SumLayout sl = sum_layout();
  const std::vector<int>& counts = sl.counts;
  const std::vector<int32_t>& off = sl.off;
  const render::KeptLayout& layout = sl.layout;
  const int R = int(counts.size()), K = sl.K;
  for (int C : {256, 20, 8, 7, 3}) {  // vector widths 16, 4, 8, 1, 1
    CAPTURE(C);
    const auto w = testing::random_uniform(K, 21, 0.0f, 1.0f);
    const auto v = testing::random_normal(size_t(K) * C, 22);
    const auto gv = testing::to_double(testing::random_normal(size_t(R) * C, 23));
    const auto ga = testing::to_double(testing::random_normal(R, 24));
    auto ref = [&](const std::vector<double>& wd, const std::vector<double>& vd, std::vector<double>* acc) {
      std::vector<double> out(size_t(R) * C, 0.0);
      if (acc) acc->assign(R, 0.0);
      for (int r = 0; r < R; ++r)
        for (int k = off[r]; k < off[r] + counts[r]; ++k) {
          if (acc) (*acc)[r] += wd[k];
          for (int c = 0; c < C; ++c) out[size_t(r) * C + c] += wd[k] * vd[size_t(k) * C + c];
        }
      return out;
    };
    Tensor tw = Tensor::from_host(w, {K}), tv = Tensor::from_host(v, {K, C});
    auto out = render::composite_values_forward(layout, tw, tv);
    std::vector<double> acc;
    const auto want = ref(testing::to_double(w), testing::to_double(v), &acc);
    check_close(out.value.to_host(), want, 1e-5, 1e-6, "composited values");
    check_close(out.acc.to_host(), acc, 1e-6, 1e-7, "kept acc");

    auto loss = [&](const std::vector<double>& wd, const std::vector<double>& vd) {
      std::vector<double> a;
      return testing::dot(ref(wd, vd, &a), gv) + testing::dot(a, ga);
    };
    const auto wd = testing::to_double(w), vd = testing::to_double(v);
    const auto fd_w = testing::finite_difference([&](const std::vector<double>& x) { return loss(x, vd); }, wd, 1e-6);
    std::vector<size_t> probe;  // a sample of the value entries (all of them at small C)
    for (size_t i = 0; i < vd.size(); i += (C > 20 ? 37 : 1)) probe.push_back(i);
    const auto fd_v =
        testing::finite_difference_at([&](const std::vector<double>& x) { return loss(wd, x); }, vd, probe, 1e-6);
    auto g = render::composite_values_backward(layout, tw, tv,
                                               Tensor::from_host(std::vector<float>(gv.begin(), gv.end()), {R, C}),
                                               Tensor::from_host(std::vector<float>(ga.begin(), ga.end()), {R}));
    check_close(g.dw.to_host(), fd_w, 1e-4, 1e-5, "dw");
    const auto dv = g.dvalues.to_host();
    std::vector<float> got;
    std::vector<double> want_v;
    for (size_t i = 0; i < probe.size(); ++i) got.push_back(dv[probe[i]]), want_v.push_back(fd_v[i]);
    check_close(got, want_v, 1e-4, 1e-5, "dvalues");
  }
}

TEST_CASE("weighted sum over indexed rows: the double reference and the gathered sum, every vector width") {
  const SumLayout sl = sum_layout();
  const std::vector<int>& counts = sl.counts;
  const std::vector<int32_t>& off = sl.off;
  const render::KeptLayout& layout = sl.layout;
  const int K = sl.K;
  const int N = 19;  // value rows: more than entries, some read twice, some never
  std::vector<int32_t> rows(K);
  for (int k = 0; k < K; ++k) rows[k] = (7 * k + 3) % N;
  rows[4] = rows[2];
  for (int C : {256, 72, 20, 7}) {  // vector widths 16, 8, 4, 1
    CAPTURE(C);
    const auto w = testing::random_uniform(K, 31, 0.0f, 1.0f);
    const auto v = testing::random_normal(size_t(N) * C, 32);
    std::vector<double> want(counts.size() * C, 0.0), acc(counts.size(), 0.0);
    for (size_t r = 0; r < counts.size(); ++r)
      for (int k = off[r]; k < off[r] + counts[r]; ++k) {
        acc[r] += w[k];
        for (int c = 0; c < C; ++c) want[r * C + c] += double(w[k]) * v[size_t(rows[k]) * C + c];
      }
    const Tensor tw = Tensor::from_host(w, {K}), tv = Tensor::from_host(v, {N, C}), tr = Tensor::from_host(rows, {K});
    const auto out = render::composite_values_forward(layout, tw, tv, tr);
    check_close(out.value.to_host(), want, 1e-5, 1e-6, "indexed values");
    check_close(out.acc.to_host(), acc, 1e-6, 1e-7, "indexed acc");
    // The same sums, in the same order, as gathering the rows first.
    const auto gathered = render::composite_values_forward(layout, tw, render::gather_rows(tv, tr, K));
    CHECK(out.value.to_host() == gathered.value.to_host());
  }
  testing::expect_error(
      [&] { render::composite_values_forward(layout, Tensor::zeros({K}), Tensor::zeros({N, 8}), Tensor::zeros({K})); },
      "dtype");
  testing::expect_error([&] {
    render::composite_values_forward(layout, Tensor::zeros({K}), Tensor::zeros({N, 8}),
                                     Tensor::from_host(std::vector<int32_t>(K - 1, 0), {K - 1}));
  }, "rows");
}

TEST_CASE("merging a group's kept samples step by step") {
  // Two groups of two rays, step 0.1. Group 0: ray 0 at steps 1, 2, 3; ray 1 at 2, 3, 4 (its t off the
  // grid by 0.3 of a step: rounded to the nearest). Group 1: ray 2 keeps nothing, ray 3 keeps steps 5
  // (weight 0) and 6.
  const std::vector<int32_t> ray = {0, 0, 0, 1, 1, 1, 3, 3};
  const std::vector<float> t = {0.1f, 0.2f, 0.3f, 0.23f, 0.33f, 0.43f, 0.5f, 0.6f};
  const std::vector<float> w = {0.2f, 0.3f, 0.1f, 0.1f, 0.0f, 0.4f, 0.0f, 0.5f};
  const render::StepMerge m = render::merge_group_steps(ray, t, w, 4, 2, 0.1f);
  CHECK(m.group_offset == std::vector<int32_t>{0, 4});
  CHECK(m.group_count == std::vector<int32_t>{4, 2});
  CHECK(m.point_count == std::vector<int32_t>{1, 2, 2, 1, 1, 1});
  CHECK(m.point_offset == std::vector<int32_t>{0, 1, 3, 5, 6, 7});
  CHECK(m.order == std::vector<int32_t>{0, 1, 3, 2, 4, 5, 6, 7});
  const std::vector<float> pw = {0.1f, 0.2f, 0.05f, 0.2f, 0.0f, 0.25f};
  for (size_t i = 0; i < pw.size(); ++i) CHECK(m.point_weight[i] == doctest::Approx(pw[i]).epsilon(1e-6));
  // Shares: w / the point's sum; a point of zero weight shares equally (its mean stays defined).
  const std::vector<float> share = {1.0f, 0.75f, 0.25f, 1.0f, 0.0f, 1.0f, 1.0f, 1.0f};
  for (size_t i = 0; i < share.size(); ++i) CHECK(m.share[i] == doctest::Approx(share[i]).epsilon(1e-6));
  // The summed point weights are the group's mean kept opacity.
  CHECK(m.point_weight[0] + m.point_weight[1] + m.point_weight[2] + m.point_weight[3] ==
        doctest::Approx((0.6 + 0.5) / 2).epsilon(1e-6));
  // One ray a group: each sample its own point, share 1, weight w.
  const render::StepMerge one = render::merge_group_steps(ray, t, w, 4, 1, 0.1f);
  CHECK(one.points() == 8);
  CHECK(one.group_count == std::vector<int32_t>{3, 3, 0, 2});
  for (size_t i = 0; i < w.size(); ++i) CHECK(one.point_weight[i] == w[i]);
  // Nothing kept.
  const render::StepMerge none = render::merge_group_steps({}, {}, {}, 6, 3, 0.1f);
  CHECK(none.points() == 0);
  CHECK(none.group_count == std::vector<int32_t>{0, 0});
  // Bad lists: clear errors.
  testing::expect_error([&] { render::merge_group_steps(ray, t, w, 3, 2, 0.1f); }, "not whole groups");
  testing::expect_error([&] { render::merge_group_steps(ray, t, w, 2, 2, 0.1f); }, "outside the 2 rays");
  testing::expect_error([&] { render::merge_group_steps(ray, t, w, 4, 2, 0.0f); }, "step");
  testing::expect_error([&] { render::merge_group_steps(ray, t, {0.1f}, 4, 2, 0.1f); }, "weights");
  testing::expect_error([&] { render::merge_group_steps({0, 0}, {0.2f, 0.1f}, {1, 1}, 2, 2, 0.1f); }, "out of order");
  testing::expect_error([&] { render::merge_group_steps({1, 0}, {0.1f, 0.2f}, {1, 1}, 2, 2, 0.1f); }, "out of order");
}

TEST_CASE("weighted sum over kept samples: no kept samples, a ray of zero weights, shape errors") {
  const std::vector<int> counts = {0, 0};
  Samples s = make_samples(counts, {}, {});
  const render::KeptLayout layout = all_kept(s, counts);
  auto out = render::composite_values_forward(layout, Tensor({0}), Tensor({0, 256}));
  CHECK(out.value.to_host() == std::vector<float>(2 * 256, 0.0f));
  CHECK(out.acc.to_host() == std::vector<float>{0.0f, 0.0f});
  // All weights zero (a background ray that kept samples anyway): value 0, acc 0, dvalues 0.
  const std::vector<int> c2 = {4};
  Samples s2 = make_samples(c2, std::vector<float>(4, 1.0f), std::vector<float>(4, 0.1f));
  const auto l2 = all_kept(s2, c2);
  auto o2 = render::composite_values_forward(l2, Tensor::zeros({4}), Tensor::full({4, 256}, 3.0f));
  CHECK(o2.value.to_host() == std::vector<float>(256, 0.0f));
  auto g2 = render::composite_values_backward(l2, Tensor::zeros({4}), Tensor::full({4, 256}, 3.0f),
                                              Tensor::full({1, 256}, 1.0f), Tensor());
  CHECK(g2.dvalues.to_host() == std::vector<float>(4 * 256, 0.0f));
  CHECK(g2.dw.to_host() == std::vector<float>(4, 768.0f));
  testing::expect_error([&] { render::composite_values_forward(l2, Tensor::zeros({3}), Tensor::zeros({4, 8})); },
                        "weights");
  testing::expect_error([&] { render::composite_values_forward(l2, Tensor::zeros({4}), Tensor::zeros({5, 8})); },
                        "values have shape");
}

namespace {
// The distortion loss as its definition's double sum (no prefix sums): sum_ij w_i w_j |u_i - u_j| + d/3 sum w_i^2.
std::vector<double> ref_distortion(const std::vector<int>& counts, const std::vector<double>& w,
                                   const std::vector<float>& t, double inv_len, double d, double scale) {
  std::vector<double> loss;
  size_t o = 0;
  for (int n : counts) {
    double L = 0;
    for (int i = 0; i < n; ++i) {
      for (int j = 0; j < n; ++j) L += w[o + i] * w[o + j] * std::fabs((double(t[o + i]) - t[o + j]) * inv_len);
      L += d / 3.0 * w[o + i] * w[o + i];
    }
    loss.push_back(scale * L);
    o += size_t(n);
  }
  return loss;
}
}  // namespace

TEST_CASE("distortion term: forward against its double sum, backward against central differences, hard rays") {
  // Rays: no samples, one sample, a spread fog, a crisp surface, all weight at the first sample, zero weight.
  const std::vector<int> counts = {0, 1, 40, 12, 5, 7};
  int S = 0;
  for (int n : counts) S += n;
  std::vector<float> t, w;
  const auto noise = testing::random_uniform(size_t(S), 41, 0.0f, 1.0f);
  size_t k = 0;
  for (size_t r = 0; r < counts.size(); ++r) {
    float tt = 0.5f + 0.1f * float(r);
    for (int i = 0; i < counts[r]; ++i, ++k) {
      tt += 0.02f + 0.01f * noise[k];  // increasing along the ray, uneven gaps (skipped space)
      t.push_back(tt);
      float wi = 0.0f;
      if (r == 1) wi = 0.7f;
      if (r == 2) wi = 0.02f + 0.01f * noise[k];         // a fog: about 1 in all, spread along the ray
      if (r == 3) wi = (i == 6 ? 0.8f : (i == 5 || i == 7 ? 0.08f : 0.001f));  // a surface
      if (r == 4) wi = (i == 0 ? 1.0f : 0.0f);
      w.push_back(wi);
    }
  }
  const Samples s = make_samples(counts, t, std::vector<float>(t.size(), 0.1f));
  const double inv_len = 1.0 / 1.7, d = 0.01 / 1.7, scale = 0.25;
  const render::Distortion got =
      render::distortion_forward_backward(s, Tensor::from_host(w, {s.count}), float(inv_len), float(d), float(scale));
  const std::vector<double> want = ref_distortion(counts, testing::to_double(w), t, inv_len, d, scale);
  check_close(got.loss.to_host(), want, 1e-5, 1e-7, "distortion per ray");
  const auto loss = got.loss.to_host();
  CHECK(loss[0] == 0.0f);                                       // no samples
  CHECK(loss[1] == doctest::Approx(scale * d / 3 * 0.49));      // one sample: its own interval only
  CHECK(loss[2] > 20 * loss[3]);                                // a fog costs more than a surface
  CHECK(loss[5] == 0.0f);                                       // no weight
  // dL/dw_i by central differences of the reference, entry by entry (the loss is quadratic in w).
  const auto dw = got.dw.to_host();
  std::vector<double> num(w.size());
  const double h = 1e-3;
  for (size_t i = 0; i < w.size(); ++i) {
    std::vector<double> wp = testing::to_double(w), wm = wp;
    wp[i] += h;
    wm[i] -= h;
    const auto lp = ref_distortion(counts, wp, t, inv_len, d, scale), lm = ref_distortion(counts, wm, t, inv_len, d, scale);
    double sp = 0, sm = 0;
    for (size_t r = 0; r < lp.size(); ++r) sp += lp[r], sm += lm[r];
    num[i] = (sp - sm) / (2 * h);
  }
  check_close(dw, num, 1e-4, 1e-6, "distortion dw");
  // Bad scales are refused by name; an empty ray list gives empty outputs.
  testing::expect_error([&] { render::distortion_forward_backward(s, Tensor::from_host(w, {s.count}), 0.0f, 0.01f, 1.0f); },
                        "distortion: bad scales");
  const Samples e = make_samples({}, {}, {});
  const render::Distortion none = render::distortion_forward_backward(e, Tensor({0}), 1.0f, 0.01f, 1.0f);
  CHECK(none.loss.numel() == 0);
}
