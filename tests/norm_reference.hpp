// Double-precision CPU references for the statistics, normalisation and loss ops (tests only).
// Channels are nc = N*C contiguous runs of hw = H*W values, as in the kernels.
#pragma once
#include <algorithm>
#include <cmath>
#include <vector>

namespace stylerf::testing::ref {

struct Stats {
  std::vector<double> mean, std;
};

// Two-pass in double: exact enough to serve as the truth for float kernels.
inline Stats channel_stats(const std::vector<double>& x, int nc, int hw, double eps) {
  Stats s{std::vector<double>(nc), std::vector<double>(nc)};
  for (int c = 0; c < nc; ++c) {
    double m = 0;
    for (int i = 0; i < hw; ++i) m += x[size_t(c) * hw + i];
    m /= hw;
    double q = 0;
    for (int i = 0; i < hw; ++i) {
      const double d = x[size_t(c) * hw + i] - m;
      q += d * d;
    }
    s.mean[c] = m;
    s.std[c] = std::sqrt(q / hw + eps);
  }
  return s;
}

inline std::vector<double> instance_norm(const std::vector<double>& x, int nc, int hw, double eps) {
  const Stats s = channel_stats(x, nc, hw, eps);
  std::vector<double> y(x.size());
  for (int c = 0; c < nc; ++c)
    for (int i = 0; i < hw; ++i) y[size_t(c) * hw + i] = (x[size_t(c) * hw + i] - s.mean[c]) / s.std[c];
  return y;
}

inline std::vector<double> adain(const std::vector<double>& content, const std::vector<double>& style, int nc,
                                 int hw_c, int hw_s, double eps) {
  const Stats sc = channel_stats(content, nc, hw_c, eps), ss = channel_stats(style, nc, hw_s, eps);
  std::vector<double> y(content.size());
  for (int c = 0; c < nc; ++c)
    for (int i = 0; i < hw_c; ++i) {
      const size_t k = size_t(c) * hw_c + i;
      y[k] = (content[k] - sc.mean[c]) / sc.std[c] * ss.std[c] + ss.mean[c];
    }
  return y;
}

inline double mse(const std::vector<double>& a, const std::vector<double>& b) {
  double s = 0;
  for (size_t i = 0; i < a.size(); ++i) s += (a[i] - b[i]) * (a[i] - b[i]);
  return s / double(a.size());
}

inline double style_loss(const std::vector<double>& a, const std::vector<double>& b, int nc, int hw_a, int hw_b,
                         double eps) {
  const Stats sa = channel_stats(a, nc, hw_a, eps), sb = channel_stats(b, nc, hw_b, eps);
  return mse(sa.mean, sb.mean) + mse(sa.std, sb.std);
}

inline double max_abs(const std::vector<double>& v) {
  double m = 0;
  for (double x : v) m = std::max(m, std::fabs(x));
  return m;
}

}  // namespace stylerf::testing::ref
