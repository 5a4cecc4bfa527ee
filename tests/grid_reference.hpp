// Double-precision reference of the VM grid (sampling, features, their gradient, TV, L1), written from
// the layout documented in lib/field/vm_grid.hpp, and the special test points. Used by test_grid.cpp and
// test_grid_scatter.cpp.
#pragma once
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <utility>
#include <vector>

#include "lib/field/vm_grid.hpp"
#include "tests/testing.hpp"

namespace stylerf::testing {

using field::DensityActivation;

// ---- double-precision reference, written from the layout documented in vm_grid.hpp -------------------
struct GridRef {
  std::array<int, 3> res, rank;
  int U[3] = {0, 0, 1}, V[3] = {1, 2, 2}, W[3] = {2, 1, 0};
  size_t plane_off(int m) const {
    size_t o = 0;
    for (int i = 0; i < m; ++i) o += size_t(res[U[i]]) * res[V[i]] * rank[i];
    return o;
  }
  size_t line_off(int m) const {
    size_t o = plane_off(3);
    for (int i = 0; i < m; ++i) o += size_t(res[W[i]]) * rank[i];
    return o;
  }
  size_t numel() const { return line_off(3); }
  static void corner(double p, int n, int& i, double& f) {
    const double x = (p + 1.0) * 0.5 * (n - 1);
    i = std::min(std::max(int(std::floor(x)), 0), n - 2);
    f = x - i;
  }
  static bool inside(const double* p) {
    for (int a = 0; a < 3; ++a)
      if (!(p[a] >= -1.0 && p[a] <= 1.0)) return false;
    return true;
  }
  // plane_m[r] and line_m[r] at p; optionally the taps (index, weight) for gradients.
  void values(const std::vector<double>& g, int m, int r, const double* p, double& pv, double& lv,
              std::vector<std::pair<size_t, double>>* ptaps = nullptr,
              std::vector<std::pair<size_t, double>>* ltaps = nullptr) const {
    const int nu = res[U[m]], nv = res[V[m]], nw = res[W[m]], R = rank[m];
    int iu, iv, iw;
    double fu, fv, fw;
    corner(p[U[m]], nu, iu, fu);
    corner(p[V[m]], nv, iv, fv);
    corner(p[W[m]], nw, iw, fw);
    auto P = [&](int v, int u) { return plane_off(m) + (size_t(v) * nu + u) * R + r; };
    auto L = [&](int w) { return line_off(m) + size_t(w) * R + r; };
    std::pair<size_t, double> pt[4] = {{P(iv, iu), (1 - fu) * (1 - fv)},
                                       {P(iv, iu + 1), fu * (1 - fv)},
                                       {P(iv + 1, iu), (1 - fu) * fv},
                                       {P(iv + 1, iu + 1), fu * fv}};
    std::pair<size_t, double> lt[2] = {{L(iw), 1 - fw}, {L(iw + 1), fw}};
    pv = lv = 0;
    for (auto& t : pt) pv += g[t.first] * t.second;
    for (auto& t : lt) lv += g[t.first] * t.second;
    if (ptaps) ptaps->assign(pt, pt + 4);
    if (ltaps) ltaps->assign(lt, lt + 2);
  }
  double raw_density(const std::vector<double>& g, const double* p) const {
    if (!inside(p)) return 0.0;
    double s = 0;
    for (int m = 0; m < 3; ++m)
      for (int r = 0; r < rank[m]; ++r) {
        double pv, lv;
        values(g, m, r, p, pv, lv);
        s += pv * lv;
      }
    return s;
  }
  static double act(double f, DensityActivation a) {
    if (a == DensityActivation::Relu) return std::max(f, 0.0);
    const double x = f - 10.0;
    return std::max(x, 0.0) + std::log1p(std::exp(-std::fabs(x)));
  }
  double density(const std::vector<double>& g, const double* p, DensityActivation a) const {
    return inside(p) ? act(raw_density(g, p), a) : 0.0;
  }
  std::vector<double> features(const std::vector<double>& g, const double* p) const {
    std::vector<double> f;
    for (int m = 0; m < 3; ++m)
      for (int r = 0; r < rank[m]; ++r) {
        double pv = 0, lv = 0;
        if (inside(p)) values(g, m, r, p, pv, lv);
        f.push_back(pv * lv);
      }
    return f;
  }
  // Analytic d(sum_i gfeat_i . feat_i)/dparams (checked against finite differences below).
  std::vector<double> features_grad(const std::vector<double>& g, const std::vector<double>& pts,
                                    const std::vector<double>& gfeat) const {
    std::vector<double> d(g.size(), 0.0);
    const int F = rank[0] + rank[1] + rank[2];
    for (size_t i = 0; i < pts.size() / 3; ++i) {
      const double* p = &pts[3 * i];
      if (!inside(p)) continue;
      int k = 0;
      for (int m = 0; m < 3; ++m)
        for (int r = 0; r < rank[m]; ++r, ++k) {
          double pv, lv;
          std::vector<std::pair<size_t, double>> pt, lt;
          values(g, m, r, p, pv, lv, &pt, &lt);
          const double gg = gfeat[i * F + k];
          for (auto& t : pt) d[t.first] += gg * lv * t.second;
          for (auto& t : lt) d[t.first] += gg * pv * t.second;
        }
    }
    return d;
  }
  double tv(const std::vector<double>& g) const {
    double s = 0;
    for (int m = 0; m < 3; ++m) {
      const int nu = res[U[m]], nv = res[V[m]], R = rank[m];
      double su = 0, sv = 0;
      for (int v = 0; v < nv; ++v)
        for (int u = 0; u < nu; ++u)
          for (int r = 0; r < R; ++r) {
            const double x = g[plane_off(m) + (size_t(v) * nu + u) * R + r];
            if (u + 1 < nu) su += std::pow(g[plane_off(m) + (size_t(v) * nu + u + 1) * R + r] - x, 2);
            if (v + 1 < nv) sv += std::pow(g[plane_off(m) + (size_t(v + 1) * nu + u) * R + r] - x, 2);
          }
      s += su / (double(R) * nv * (nu - 1)) + sv / (double(R) * (nv - 1) * nu);
    }
    return s;
  }
  double l1(const std::vector<double>& g) const {
    size_t starts[7] = {plane_off(0), plane_off(1), plane_off(2), line_off(0), line_off(1), line_off(2), numel()};
    double s = 0;
    for (int q = 0; q < 6; ++q) {
      double part = 0;
      for (size_t k = starts[q]; k < starts[q + 1]; ++k) part += std::fabs(g[k]);
      s += part / double(starts[q + 1] - starts[q]);
    }
    return s;
  }
};

// Random points in the box plus the special ones: all 8 corners, edge midpoints, face points, exact grid
// nodes, points just outside, NaN.
inline std::vector<float> grid_test_points(int n_random, uint64_t seed, bool with_outside) {
  std::vector<float> p = testing::random_uniform(size_t(3) * n_random, seed, -1.0f, 1.0f);
  for (int c = 0; c < 8; ++c)
    for (int a = 0; a < 3; ++a) p.push_back((c >> a) & 1 ? 1.0f : -1.0f);
  const float special[][3] = {{1, 0, 0}, {-1, 0.5f, 1}, {0, 1, -1}, {0.5f, 0.5f, 0.5f}, {0, 0, 0},
                              {1, 1, 0.25f}, {-1, -1, 0.3f}, {0.25f, -0.5f, 1}};
  for (auto& s : special) p.insert(p.end(), s, s + 3);
  if (with_outside) {
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const float out[][3] = {{1.0001f, 0, 0}, {0, -1.5f, 0}, {0, 0, 3}, {nan, 0, 0}, {-2, -2, -2}};
    for (auto& s : out) p.insert(p.end(), s, s + 3);
  }
  return p;
}

}  // namespace stylerf::testing
