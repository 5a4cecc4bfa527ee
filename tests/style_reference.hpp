// Plain double-precision CPU references of SICT and DST (lib/style/sict.hpp, lib/style/dst.hpp), written
// from the formulas in docs/design.md with loops and nothing shared with the device code. Rows layout: points
// [K][256], style positions [L][256], rays [R][32]; weights in nn::linear's [in][out] layout.
#pragma once
#include <algorithm>
#include <cmath>
#include <vector>

namespace stylerf::testing::style_ref {

using Vec = std::vector<double>;
constexpr int C = 256, E = 32;
constexpr double kEps = 1e-5;

enum class Mode { VolumeAdaptive, VanillaIn, None };

// y[n][out] = x[n][in] W[in][out] + b[out]
inline Vec linear(const Vec& x, const Vec& w, const Vec& b, int n, int in, int out) {
  Vec y(size_t(n) * out);
  for (int r = 0; r < n; ++r)
    for (int j = 0; j < out; ++j) {
      double s = b.empty() ? 0.0 : b[j];
      for (int i = 0; i < in; ++i) s += x[size_t(r) * in + i] * w[size_t(i) * out + j];
      y[size_t(r) * out + j] = s;
    }
  return y;
}

inline void column_mean_var(const Vec& x, int n, int cols, int ddof, Vec& mean, Vec& var) {
  mean.assign(cols, 0.0);
  var.assign(cols, 0.0);
  for (int r = 0; r < n; ++r)
    for (int j = 0; j < cols; ++j) mean[j] += x[size_t(r) * cols + j];
  for (double& m : mean) m /= n;
  for (int r = 0; r < n; ++r)
    for (int j = 0; j < cols; ++j) {
      const double d = x[size_t(r) * cols + j] - mean[j];
      var[j] += d * d;
    }
  for (double& v : var) v /= double(n - ddof);
}

// SICT: x [K][256] -> [K][32]. rmean / rvar: the running statistics (used in VolumeAdaptive evaluation).
inline Vec sict(const Vec& x, int K, const Vec& w, const Vec& b, Mode mode, bool training, const Vec& rmean,
                const Vec& rvar) {
  Vec normed = x;
  if (mode != Mode::None) {
    Vec mean = rmean, var = rvar;
    if (mode == Mode::VanillaIn || training) column_mean_var(x, K, C, 0, mean, var);
    for (int r = 0; r < K; ++r)
      for (int j = 0; j < C; ++j) normed[size_t(r) * C + j] = (x[size_t(r) * C + j] - mean[j]) / std::sqrt(var[j] + kEps);
  }
  const Vec qkv = linear(normed, w, b, K, C, 3 * E);
  Vec out(size_t(K) * E);
  for (int r = 0; r < K; ++r) {
    const double* q = &qkv[size_t(r) * 3 * E];
    const double *k = q + E, *v = q + 2 * E;
    for (int i = 0; i < E; ++i) {
      double m = -1e300;
      for (int j = 0; j < E; ++j) m = std::max(m, q[i] * k[j]);
      double z = 0, acc = 0;
      for (int j = 0; j < E; ++j) {
        const double e = std::exp(q[i] * k[j] - m);
        z += e;
        acc += e * v[j];
      }
      out[size_t(r) * E + i] = acc / z;
    }
  }
  return out;
}

// The running statistics after one training call (from rmean / rvar; unbiased variance, momentum 1e-4).
inline void running_after(const Vec& x, int K, Vec& rmean, Vec& rvar) {
  Vec mean, var;
  column_mean_var(x, K, C, 1, mean, var);
  for (int j = 0; j < C; ++j) {
    rmean[j] = (1 - 1e-4) * rmean[j] + 1e-4 * mean[j];
    rvar[j] = (1 - 1e-4) * rvar[j] + 1e-4 * var[j];
  }
}

struct DstParams {
  Vec w0, b0, w2, b2, w4, b4, fc_w, fc_b, unzip;  // [in][out]
};

struct Code {
  Vec mean, std, T;  // T [32][32]
};

inline Code style_code(const Vec& s, int L, const DstParams& p) {
  Code c;
  Vec var;
  column_mean_var(s, L, C, 1, c.mean, var);
  c.std.resize(C);
  for (int j = 0; j < C; ++j) c.std[j] = std::sqrt(var[j]);
  Vec centred = s;
  for (int r = 0; r < L; ++r)
    for (int j = 0; j < C; ++j) centred[size_t(r) * C + j] -= c.mean[j];
  Vec h1 = linear(centred, p.w0, p.b0, L, C, 128);
  for (double& v : h1) v = std::max(v, 0.0);
  Vec h2 = linear(h1, p.w2, p.b2, L, 128, 64);
  for (double& v : h2) v = std::max(v, 0.0);
  const Vec e = linear(h2, p.w4, p.b4, L, 64, E);
  Vec cov(size_t(E) * E, 0.0);
  for (int a = 0; a < E; ++a)
    for (int b = 0; b < E; ++b) {
      double s2 = 0;
      for (int r = 0; r < L; ++r) s2 += e[size_t(r) * E + a] * e[size_t(r) * E + b];
      cov[size_t(a) * E + b] = s2 / L;
    }
  c.T = linear(cov, p.fc_w, p.fc_b, 1, E * E, E * E);
  return c;
}

// y[r][o] = sum_a (sum_b T[a][b] c[r][b]) U[a][o] * std[o] + acc[r] * mean[o] (bias)
inline Vec dst_apply(const Vec& cvals, const Vec& acc, int R, const Code& code, const Vec& unzip, bool bias) {
  Vec y(size_t(R) * C);
  for (int r = 0; r < R; ++r) {
    double tc[E];
    for (int a = 0; a < E; ++a) {
      double s = 0;
      for (int b = 0; b < E; ++b) s += code.T[size_t(a) * E + b] * cvals[size_t(r) * E + b];
      tc[a] = s;
    }
    for (int o = 0; o < C; ++o) {
      double s = 0;
      for (int a = 0; a < E; ++a) s += tc[a] * unzip[size_t(a) * C + o];
      y[size_t(r) * C + o] = s * code.std[o] + (bias ? acc[r] * code.mean[o] : 0.0);
    }
  }
  return y;
}

}  // namespace stylerf::testing::style_ref
