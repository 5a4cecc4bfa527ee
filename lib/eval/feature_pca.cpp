#include "lib/eval/feature_pca.hpp"

#include <algorithm>
#include <cmath>

#include "host/error.hpp"

namespace stylerf::eval {

using host::Error;

std::vector<float> planar_to_rows(const std::vector<float>& chw, int channels, int pixels) {
  if (chw.size() != size_t(channels) * pixels) throw Error("planar_to_rows: size does not match channels x pixels");
  std::vector<float> rows(chw.size());
  for (int c = 0; c < channels; ++c)
    for (int i = 0; i < pixels; ++i) rows[size_t(i) * channels + c] = chw[size_t(c) * pixels + i];
  return rows;
}

FeaturePca FeaturePca::fit(const std::vector<float>& features, int C, int max_samples) {
  if (C < 1 || features.size() % size_t(C) || features.empty())
    throw Error("feature PCA: " + std::to_string(features.size()) + " values are not rows of " + std::to_string(C));
  const size_t n = features.size() / C;
  const size_t step = std::max<size_t>(1, n / size_t(std::max(1, max_samples)));
  std::vector<size_t> rows;
  for (size_t i = 0; i < n; i += step) rows.push_back(i);
  FeaturePca p;
  p.channels = C;
  p.mean.assign(C, 0.0);
  for (size_t r : rows)
    for (int c = 0; c < C; ++c) p.mean[c] += features[r * C + c];
  for (auto& m : p.mean) m /= double(rows.size());
  std::vector<double> cov(size_t(C) * C, 0.0), x(C);
  for (size_t r : rows) {
    for (int c = 0; c < C; ++c) x[c] = features[r * C + c] - p.mean[c];
    for (int a = 0; a < C; ++a)
      for (int b = a; b < C; ++b) cov[size_t(a) * C + b] += x[a] * x[b];
  }
  for (int a = 0; a < C; ++a)
    for (int b = 0; b < a; ++b) cov[size_t(a) * C + b] = cov[size_t(b) * C + a];
  p.components.assign(size_t(3) * C, 0.0);
  for (int k = 0; k < 3; ++k) {
    std::vector<double> v(C), w(C);
    for (int c = 0; c < C; ++c) v[c] = 1.0 + 0.01 * ((c * 7 + k * 3) % 11);  // fixed start: deterministic
    for (int it = 0; it < 200; ++it) {
      for (int a = 0; a < C; ++a) {
        double s = 0;
        for (int b = 0; b < C; ++b) s += cov[size_t(a) * C + b] * v[b];
        w[a] = s;
      }
      double norm = 0;
      for (double q : w) norm += q * q;
      norm = std::sqrt(norm);
      if (!(norm > 1e-30)) break;  // nothing left (constant features): the component stays 0
      for (int c = 0; c < C; ++c) v[c] = w[c] / norm;
    }
    double norm = 0;
    for (double q : v) norm += q * q;
    if (!(norm > 0.5)) std::fill(v.begin(), v.end(), 0.0);
    int big = 0;
    for (int c = 1; c < C; ++c)
      if (std::fabs(v[c]) > std::fabs(v[big])) big = c;
    if (v[big] < 0)
      for (auto& q : v) q = -q;
    // Deflate: cov -= lambda v v^T.
    double lambda = 0;
    for (int a = 0; a < C; ++a) {
      double s = 0;
      for (int b = 0; b < C; ++b) s += cov[size_t(a) * C + b] * v[b];
      lambda += v[a] * s;
    }
    for (int a = 0; a < C; ++a)
      for (int b = 0; b < C; ++b) cov[size_t(a) * C + b] -= lambda * v[a] * v[b];
    std::copy(v.begin(), v.end(), p.components.begin() + size_t(k) * C);
  }
  // Colour range from the fit set's projections.
  for (int k = 0; k < 3; ++k) {
    std::vector<double> proj;
    for (size_t r : rows) {
      double s = 0;
      for (int c = 0; c < C; ++c) s += (features[r * C + c] - p.mean[c]) * p.components[size_t(k) * C + c];
      proj.push_back(s);
    }
    std::sort(proj.begin(), proj.end());
    p.lo[k] = proj[proj.size() / 100];
    p.hi[k] = proj[std::min(proj.size() - 1, proj.size() * 99 / 100)];
    if (!(p.hi[k] > p.lo[k])) p.hi[k] = p.lo[k] + 1.0;
  }
  return p;
}

std::vector<float> FeaturePca::apply(const std::vector<float>& features) const {
  const int C = channels;
  if (C < 1 || features.size() % size_t(C)) throw Error("feature PCA: rows do not have the fitted channel count");
  const size_t n = features.size() / C;
  std::vector<float> out(n * 3);
  for (size_t r = 0; r < n; ++r)
    for (int k = 0; k < 3; ++k) {
      double s = 0;
      for (int c = 0; c < C; ++c) s += (features[r * C + c] - mean[c]) * components[size_t(k) * C + c];
      out[r * 3 + k] = float(std::clamp((s - lo[k]) / (hi[k] - lo[k]), 0.0, 1.0));
    }
  return out;
}

}  // namespace stylerf::eval
