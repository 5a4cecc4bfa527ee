#include "lib/model/block_refine.hpp"

#include <algorithm>
#include <cmath>

#include "host/error.hpp"

namespace stylerf::model {

std::vector<uint8_t> blocks_to_refine(const std::vector<float>& c, int channels, const std::vector<float>& acc, int w,
                                      int h, float contrast) {
  const size_t n = size_t(w) * size_t(h);
  if (w < 1 || h < 1 || channels < 1 || c.size() != n * size_t(channels) || acc.size() != n)
    throw host::Error("blocks_to_refine: a " + std::to_string(w) + "x" + std::to_string(h) + " map of " +
                      std::to_string(channels) + " channels does not match " + std::to_string(c.size()) +
                      " content values and " + std::to_string(acc.size()) + " opacities");
  if (!(contrast > 0.0f)) return std::vector<uint8_t>(n, 1);
  // 1 / s_k per channel (0 for a constant channel), in double: a map of 47k blocks.
  std::vector<double> inv_s(size_t(channels), 0.0);
  for (int k = 0; k < channels; ++k) {
    double s = 0, s2 = 0;
    for (size_t b = 0; b < n; ++b) {
      const double v = c[b * channels + size_t(k)];
      s += v;
      s2 += v * v;
    }
    const double mean = s / double(n), var = std::max(0.0, s2 / double(n) - mean * mean);
    inv_s[size_t(k)] = var > 1e-12 ? 1.0 / std::sqrt(var) : 0.0;
  }
  const double limit2 = double(contrast) * contrast * channels;  // on the sum over channels
  auto differs = [&](size_t a, size_t b) {
    if (std::abs(acc[a] - acc[b]) > contrast) return true;
    double d2 = 0;
    for (int k = 0; k < channels; ++k) {
      const double d = (double(c[a * channels + size_t(k)]) - c[b * channels + size_t(k)]) * inv_s[size_t(k)];
      d2 += d * d;
    }
    return d2 > limit2;
  };
  std::vector<uint8_t> out(n, 0);
  // Each unordered pair once (right, down, down-right, down-left); both blocks of a differing pair refine.
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const size_t a = size_t(y) * w + x;
      const int nx[4] = {x + 1, x, x + 1, x - 1}, ny[4] = {y, y + 1, y + 1, y + 1};
      for (int j = 0; j < 4; ++j) {
        if (nx[j] < 0 || nx[j] >= w || ny[j] >= h) continue;
        const size_t b = size_t(ny[j]) * w + nx[j];
        if ((out[a] && out[b]) || !differs(a, b)) continue;
        out[a] = out[b] = 1;
      }
    }
  return out;
}

}  // namespace stylerf::model
