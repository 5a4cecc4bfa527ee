#include "lib/field/appearance_head.hpp"

#include <cmath>
#include <random>

#include "host/error.hpp"
#include "host/gemm.hpp"
#include "host/launch.hpp"

namespace stylerf::field {

using host::gemm;
using host::launch;
using host::matmul;
using host::Trans;

static Tensor uniform(host::Shape shape, float bound, std::mt19937_64& rng, const char* what) {
  std::uniform_real_distribution<float> d(-bound, bound);
  std::vector<float> v(static_cast<size_t>(host::shape_numel(shape)));
  for (auto& x : v) x = d(rng);
  return Tensor::from_host(v, shape, what);
}

AppearanceHead AppearanceHead::create(const AppearanceHeadConfig& cfg, uint64_t seed) {
  if (cfg.features < 1 || cfg.basis_dim < 1 || cfg.hidden < 1 || cfg.view_pe < 0)
    throw host::Error("appearance head: bad configuration");
  std::mt19937_64 rng(seed);
  AppearanceHead h;
  h.cfg = cfg;
  const int D = cfg.input_dim(), H = cfg.hidden;
  h.basis = uniform({cfg.features, cfg.basis_dim}, 1.0f / std::sqrt(float(cfg.features)), rng, "appearance basis");
  h.w1 = uniform({D, H}, 1.0f / std::sqrt(float(D)), rng, "head w1");
  h.b1 = uniform({H}, 1.0f / std::sqrt(float(D)), rng, "head b1");
  h.w2 = uniform({H, H}, 1.0f / std::sqrt(float(H)), rng, "head w2");
  h.b2 = uniform({H}, 1.0f / std::sqrt(float(H)), rng, "head b2");
  h.w3 = uniform({H, 3}, 1.0f / std::sqrt(float(H)), rng, "head w3");
  h.b3 = Tensor::zeros({3}, "head b3");
  return h;
}

std::vector<Tensor*> AppearanceHead::params() { return {&basis, &w1, &b1, &w2, &b2, &w3, &b3}; }
std::vector<Tensor*> HeadGrads::params() { return {&basis, &w1, &b1, &w2, &b2, &w3, &b3}; }

// y = act(x W + b) into a fresh [S, out] tensor; act 0 relu, 1 sigmoid.
static Tensor dense(const Tensor& x, const Tensor& W, const Tensor& b, int act) {
  const int S = static_cast<int>(x.dim(0)), C = static_cast<int>(W.dim(1));
  Tensor y({S, C}, "head activation");
  if (S == 0) return y;
  matmul(x, Trans::No, W, Trans::No, y);
  launch("grid", "bias_act_forward", {size_t(S) * C}, y, b, S, C, act);
  return y;
}

Tensor appearance_forward(const AppearanceHead& head, const Tensor& feat, const Tensor& view_dirs,
                          HeadCache* cache) {
  const auto& cfg = head.cfg;
  if (feat.ndim() != 2 || feat.dim(1) != cfg.features)
    throw host::Error("appearance_forward: features have shape " + host::shape_str(feat.shape()) + ", expected [S, " +
                      std::to_string(cfg.features) + "]");
  const int S = static_cast<int>(feat.dim(0));
  Tensor h0({S, cfg.basis_dim}, "basis output");
  if (S > 0) matmul(feat, Trans::No, head.basis, Trans::No, h0);
  Tensor in = h0;
  if (cfg.view_dependent) {
    host::expect_shape(view_dirs, {S, 3}, "appearance_forward", "view_dirs");
    in = Tensor({S, cfg.input_dim()}, "head input");
    launch("grid", "head_concat_view", {size_t(S)}, h0, view_dirs, in, S, cfg.basis_dim, cfg.view_pe);
  }
  Tensor h1 = dense(in, head.w1, head.b1, 0);
  Tensor h2 = dense(h1, head.w2, head.b2, 0);
  Tensor rgb = dense(h2, head.w3, head.b3, 1);
  if (cache) *cache = HeadCache{feat, in, h1, h2, rgb};
  return rgb;
}

// Bias gradient: column sums of dz [S, C] as ones[1,S] x dz (a GEMM; deterministic).
static Tensor column_sum(const Tensor& dz) {
  const int S = static_cast<int>(dz.dim(0)), C = static_cast<int>(dz.dim(1));
  Tensor out = Tensor::zeros({1, C}, "bias gradient");
  if (S > 0) {
    Tensor ones = Tensor::full({1, S}, 1.0f, "ones");
    matmul(ones, Trans::No, dz, Trans::No, out);
  }
  return out.reshape({C});
}

// Backward of y = act(x W + b) given dy (overwritten with dz): dW = x^T dz, db = colsum dz, dx = dz W^T.
static Tensor dense_backward(const Tensor& x, const Tensor& W, const Tensor& y, Tensor dy, int act, Tensor& dW,
                             Tensor& db, bool need_dx) {
  const int S = static_cast<int>(x.dim(0)), C = static_cast<int>(W.dim(1));
  dW = Tensor::zeros(W.shape(), "head weight gradient");
  if (S > 0) {
    launch("grid", "bias_act_backward", {size_t(S) * C}, dy, y, S, C, act);
    matmul(x, Trans::Yes, dy, Trans::No, dW);
  }
  db = column_sum(dy);
  if (!need_dx) return Tensor();
  Tensor dx({S, W.dim(0)}, "head input gradient");
  if (S > 0) matmul(dy, Trans::No, W, Trans::Yes, dx);
  return dx;
}

HeadGrads appearance_backward(const AppearanceHead& head, const HeadCache& cache, const Tensor& drgb) {
  const auto& cfg = head.cfg;
  const int S = static_cast<int>(cache.feat.dim(0));
  host::expect_shape(drgb, {S, 3}, "appearance_backward", "drgb");
  HeadGrads g;
  Tensor dz3 = drgb.clone();  // bias_act_backward works in place
  Tensor dh2 = dense_backward(cache.h2, head.w3, cache.rgb, dz3, 1, g.w3, g.b3, true);
  Tensor dh1 = dense_backward(cache.h1, head.w2, cache.h2, dh2, 0, g.w2, g.b2, true);
  Tensor din = dense_backward(cache.in, head.w1, cache.h1, dh1, 0, g.w1, g.b1, true);
  // The basis output is the first basis_dim columns of din (leading dimension D).
  const int F = cfg.features, B = cfg.basis_dim, D = cfg.input_dim();
  g.basis = Tensor::zeros({F, B}, "basis gradient");
  g.dfeat = Tensor({S, F}, "feature gradient");
  if (S > 0) {
    gemm(Trans::Yes, Trans::No, F, B, S, 1.0f, cache.feat.mem(), 0, F, din.mem(), 0, D, 0.0f, g.basis.mem(), 0, B);
    gemm(Trans::No, Trans::Yes, S, F, B, 1.0f, din.mem(), 0, D, head.basis.mem(), 0, B, 0.0f, g.dfeat.mem(), 0, F);
  }
  return g;
}

}  // namespace stylerf::field
