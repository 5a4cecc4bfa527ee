// Compositing's hard cases (lib/render/weights.hpp, lib/render/composite_values.hpp, kernels/composite.cl):
// a sample with a NaN or a negative sigma adds no optical depth (weights.hpp; the march's early termination
// reads it the same way, kernels/march_density.cl). So, exactly:
//  - its weight is 0, and the ray's other weights, opacity, depth, colour and background term are bitwise
//    those of the same ray without it (it multiplies the transmittance by exp(-0) = 1 and adds 0);
//  - a ray of nothing but such samples renders the background exactly, with opacity and depth 0;
//  - its sigma and value gradients are 0, the other gradients bitwise those of the ray without it;
// and forward and backward (background term included) match a double reference and its central differences.
#include <doctest/doctest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "host/tensor.hpp"
#include "lib/render/composite_values.hpp"
#include "lib/render/scan.hpp"
#include "lib/render/weights.hpp"
#include "tests/testing.hpp"

using namespace stylerf;
using host::Tensor;
using testing::check_close;

namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();

// A ray list: per sample sigma, delta, t and a C-channel value row; per ray its sample count.
struct Rays {
  std::vector<int> counts;
  std::vector<float> sigma, delta, t, values;
};

// The double reference: x = sigma delta where sigma > 0 and delta > 0, else 0 (so NaN and negative sigma are
// empty), w = T (1 - exp(-x)), out = sum w v + (1 - acc) bg.
struct Reference {
  std::vector<double> w, acc, depth, value;
};
Reference reference(const Rays& r, const std::vector<double>& sigma, const std::vector<double>& values, int C,
                    const std::vector<float>& bg) {
  Reference out;
  out.w.assign(sigma.size(), 0.0);
  size_t k = 0;
  for (int count : r.counts) {
    double T = 1, acc = 0, depth = 0;
    std::vector<double> v(size_t(C), 0.0);
    for (int i = 0; i < count; ++i, ++k) {
      const double x = sigma[k] > 0 && r.delta[k] > 0 ? sigma[k] * r.delta[k] : 0.0;
      const double w = T * -std::expm1(-x);
      T *= std::exp(-x);
      out.w[k] = w;
      acc += w;
      depth += w * r.t[k];
      for (int c = 0; c < C; ++c) v[size_t(c)] += w * values[k * C + c];
    }
    out.acc.push_back(acc);
    out.depth.push_back(depth);
    for (int c = 0; c < C; ++c) out.value.push_back(v[size_t(c)] + (1 - acc) * bg[size_t(c)]);
  }
  return out;
}

Tensor i32(const std::vector<int32_t>& v) { return Tensor::from_host(v, {int64_t(v.size())}, "test int list"); }

struct Rendered {
  std::vector<float> w, acc, depth, value;  // value with the background
  std::vector<float> dsigma, dvalues;
};

// Both ops with every sample kept, the background added, then the backward of
// <value, gv> + <acc, ga> + <depth, gd> (as the ray pipeline chains them).
Rendered render_both_ways(const Rays& r, int C, const std::vector<float>& bg, const std::vector<float>& gv,
                          const std::vector<float>& ga, const std::vector<float>& gd) {
  const int R = int(r.counts.size());
  const int64_t S = int64_t(r.sigma.size());
  std::vector<int32_t> offsets, ray_of;
  render::exclusive_scan(r.counts, offsets);
  for (int i = 0; i < R; ++i) ray_of.insert(ray_of.end(), size_t(r.counts[size_t(i)]), i);
  render::Samples s;
  s.count = S;
  s.ray_count = i32(r.counts);
  s.ray_offset = i32(offsets);
  s.t = Tensor::from_host(r.t, {S});
  s.deltas = Tensor::from_host(r.delta, {S});
  render::KeptLayout kept;
  kept.count = S;
  kept.ray_offset = s.ray_offset;
  kept.ray_count = s.ray_count;
  kept.ray_index = i32(ray_of);
  const Tensor sigma = Tensor::from_host(r.sigma, {S}), values = Tensor::from_host(r.values, {S, C});
  const Tensor background = Tensor::from_host(bg, {C});

  const render::Weights w = render::weights_forward(s, sigma);
  render::CompositedValues cv = render::composite_values_forward(kept, w.w, values);
  render::background_forward(cv.value, w.acc, background);
  Rendered out{w.w.to_host(), w.acc.to_host(), w.depth.to_host(), cv.value.to_host(), {}, {}};

  const Tensor dvalue = Tensor::from_host(gv, {R, C});
  const render::CompositeValuesGrads cg = render::composite_values_backward(kept, w.w, values, dvalue, Tensor());
  Tensor dacc = Tensor::from_host(ga, {R});
  render::background_backward(dvalue, background, dacc, true);
  out.dsigma = render::weights_backward(s, sigma, cg.dw, dacc, Tensor::from_host(gd, {R})).to_host();
  out.dvalues = cg.dvalues.to_host();
  return out;
}

bool empty_sample(float sigma) { return !(sigma > 0.0f); }

void check_bitwise(const std::vector<float>& got, const std::vector<float>& want, const std::string& what) {
  REQUIRE(got.size() == want.size());
  int off = 0;
  for (size_t i = 0; i < got.size(); ++i)
    if (!(got[i] == want[i]) && ++off <= 3) FAIL_CHECK(what << "[" << i << "]: " << got[i] << " vs " << want[i]);
  CHECK_MESSAGE(off == 0, what << ": " << off << " entries differ");
}

}  // namespace

TEST_CASE("NaN and negative sigma are empty samples: exact weights, opacity, colour, background, gradients") {
  for (int C : {3, 16}) {  // vector widths 1 and 16 in the value kernels
    CAPTURE(C);
    Rays r;
    // ray 0: NaN, -5 and -inf among absorbing samples; ray 1: NaN only; ray 2: negative only (-1, -1e30,
    // -inf); ray 3: NaN, then 1e6 (absorbs everything), then 2; ray 4: a clean control ray.
    r.counts = {7, 3, 3, 3, 3};
    r.sigma = {2.0f, kNaN, 3.5f, -5.0f, 0.7f, -kInf, 1.2f,  //
               kNaN, kNaN, kNaN,                           //
               -1.0f, -1e30f, -kInf,                       //
               kNaN, 1e6f, 2.0f,                           //
               0.5f, 1.5f, 2.5f};
    const size_t S = r.sigma.size();
    const int R = int(r.counts.size());
    r.delta = testing::random_uniform(S, 10, 0.05f, 0.3f);
    r.t = testing::random_uniform(S, 11, 0.5f, 4.0f);
    r.values = testing::random_uniform(S * C, 12, 0.0f, 1.0f);
    const std::vector<float> bg = testing::random_uniform(size_t(C), 13, 0.1f, 0.9f);
    const auto gv = testing::random_normal(size_t(R) * C, 14), ga = testing::random_normal(size_t(R), 15),
               gd = testing::random_normal(size_t(R), 16);
    const Rendered got = render_both_ways(r, C, bg, gv, ga, gd);

    // The same rays without the empty samples.
    Rays clean;
    std::vector<size_t> kept_of;  // sample of r behind each sample of clean
    size_t k = 0;
    for (int count : r.counts) {
      int n = 0;
      for (int i = 0; i < count; ++i, ++k)
        if (!empty_sample(r.sigma[k])) {
          kept_of.push_back(k);
          clean.sigma.push_back(r.sigma[k]);
          clean.delta.push_back(r.delta[k]);
          clean.t.push_back(r.t[k]);
          clean.values.insert(clean.values.end(), r.values.begin() + long(k) * C, r.values.begin() + long(k + 1) * C);
          ++n;
        }
      clean.counts.push_back(n);
    }
    const Rendered want = render_both_ways(clean, C, bg, gv, ga, gd);

    // Forward: empty samples weigh exactly 0; everything else is bitwise the clean ray's.
    std::vector<float> w_at_clean, ds_at_clean, dv_at_clean;
    for (size_t i = 0; i < kept_of.size(); ++i) {
      w_at_clean.push_back(got.w[kept_of[i]]);
      ds_at_clean.push_back(got.dsigma[kept_of[i]]);
      dv_at_clean.insert(dv_at_clean.end(), got.dvalues.begin() + long(kept_of[i]) * C,
                         got.dvalues.begin() + long(kept_of[i] + 1) * C);
    }
    for (size_t i = 0; i < S; ++i)
      if (empty_sample(r.sigma[i])) {
        CAPTURE(i);
        CHECK(got.w[i] == 0.0f);
        CHECK(got.dsigma[i] == 0.0f);
        for (int c = 0; c < C; ++c) CHECK(got.dvalues[i * C + size_t(c)] == 0.0f);
      }
    check_bitwise(w_at_clean, want.w, "weights of the other samples");
    check_bitwise(got.acc, want.acc, "opacity");
    check_bitwise(got.depth, want.depth, "depth");
    check_bitwise(got.value, want.value, "colour over the background");
    check_bitwise(ds_at_clean, want.dsigma, "dsigma of the other samples");
    check_bitwise(dv_at_clean, want.dvalues, "dvalues of the other samples");
    // Rays 1 and 2 hold nothing: opacity and depth 0, the background exactly. Ray 3: the 1e6 sample takes it all.
    for (int ray : {1, 2}) {
      CHECK(got.acc[size_t(ray)] == 0.0f);
      CHECK(got.depth[size_t(ray)] == 0.0f);
      for (int c = 0; c < C; ++c) CHECK(got.value[size_t(ray) * C + c] == bg[size_t(c)]);
    }
    CHECK(got.w[13] == 0.0f);
    CHECK(got.w[14] == 1.0f);
    CHECK(got.w[15] == 0.0f);
    CHECK(got.acc[3] == 1.0f);
    for (int c = 0; c < C; ++c) CHECK(got.value[size_t(3) * C + c] == r.values[size_t(14) * C + c]);

    // Against the double reference and its central differences (0 at the empty samples: NaN +- h is NaN, a
    // negative sigma +- h stays negative; both empty).
    const auto sd = testing::to_double(r.sigma), vd = testing::to_double(r.values);
    const Reference ref = reference(r, sd, vd, C, bg);
    check_close(got.w, ref.w, 1e-5, 1e-6, "weights");
    check_close(got.acc, ref.acc, 1e-5, 1e-6, "opacity");
    check_close(got.depth, ref.depth, 1e-5, 1e-6, "depth");
    check_close(got.value, ref.value, 1e-5, 1e-6, "colour over the background");
    const auto gvd = testing::to_double(gv), gad = testing::to_double(ga), gdd = testing::to_double(gd);
    auto loss = [&](const std::vector<double>& sigma, const std::vector<double>& values) {
      const Reference q = reference(r, sigma, values, C, bg);
      return testing::dot(q.value, gvd) + testing::dot(q.acc, gad) + testing::dot(q.depth, gdd);
    };
    const auto fd_sigma = testing::finite_difference([&](const std::vector<double>& x) { return loss(x, vd); }, sd, 1e-6);
    const auto fd_values = testing::finite_difference([&](const std::vector<double>& x) { return loss(sd, x); }, vd, 1e-6);
    check_close(got.dsigma, fd_sigma, 1e-4, 1e-5, "dsigma");
    check_close(got.dvalues, fd_values, 1e-4, 1e-5, "dvalues");
  }
}
