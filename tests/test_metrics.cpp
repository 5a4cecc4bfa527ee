// PSNR and SSIM (lib/eval/metrics) against direct double-precision references written here.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "host/error.hpp"
#include "lib/eval/metrics.hpp"
#include "tests/testing.hpp"

using namespace stylerf;

namespace {

// SSIM straight from the definition: for every valid window position, the Gaussian-weighted 11x11 sums
// (no separability), per channel, then the mean. Shares no code with lib/eval.
double ssim_reference(const std::vector<float>& a, const std::vector<float>& b, int w, int h, int channels) {
  const int n = 11;
  const double sigma = 1.5, c1 = 0.01 * 0.01, c2 = 0.03 * 0.03;
  double win[n][n], ws = 0;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      win[i][j] = std::exp(-((i - 5) * (i - 5) + (j - 5) * (j - 5)) / (2 * sigma * sigma));
      ws += win[i][j];
    }
  double total = 0;
  int count = 0;
  for (int c = 0; c < channels; ++c)
    for (int y = 0; y + n <= h; ++y)
      for (int x = 0; x + n <= w; ++x) {
        double mx = 0, my = 0, xx = 0, yy = 0, xy = 0;
        for (int i = 0; i < n; ++i)
          for (int j = 0; j < n; ++j) {
            const double k = win[i][j] / ws;
            const double p = a[(size_t(c) * h + y + i) * w + x + j], q = b[(size_t(c) * h + y + i) * w + x + j];
            mx += k * p;
            my += k * q;
            xx += k * p * p;
            yy += k * q * q;
            xy += k * p * q;
          }
        const double vx = std::max(0.0, xx - mx * mx), vy = std::max(0.0, yy - my * my), cov = xy - mx * my;
        total += (2 * mx * my + c1) * (2 * cov + c2) / ((mx * mx + my * my + c1) * (vx + vy + c2));
        ++count;
      }
  return total / count;
}

}  // namespace

TEST_CASE("psnr: the exact formula -10 log10(mean squared error)") {
  const std::vector<float> a = {0.0f, 0.5f, 1.0f, 0.25f}, b = {0.1f, 0.5f, 0.8f, 0.25f};
  const double mse = (0.01 + 0.0 + 0.04 + 0.0) / 4.0;
  // Tolerance 1e-6 dB: the inputs are floats (0.1f, 0.8f are not exact), everything else is double.
  CHECK(eval::psnr(a, b) == doctest::Approx(-10.0 * std::log10(mse)).epsilon(1e-6));
  CHECK(eval::mse(a, b) == doctest::Approx(mse).epsilon(1e-6));
  CHECK(std::isinf(eval::psnr(a, a)));  // identical: +inf, not NaN
  CHECK_THROWS_AS(eval::psnr(a, std::vector<float>{0.0f}), host::Error);
}

TEST_CASE("ssim: identical images give exactly 1, shifted and noisy images less") {
  const int w = 32, h = 24;
  auto img = testing::random_uniform(size_t(3) * w * h, 1, 0.0f, 1.0f);
  // Smooth it a little so a shift by one pixel changes the image but keeps structure.
  std::vector<float> s(img.size());
  for (int c = 0; c < 3; ++c)
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        double acc = 0;
        int n = 0;
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            const int yy = std::clamp(y + dy, 0, h - 1), xx = std::clamp(x + dx, 0, w - 1);
            acc += img[(size_t(c) * h + yy) * w + xx];
            ++n;
          }
        s[(size_t(c) * h + y) * w + x] = float(acc / n);
      }
  CHECK(eval::ssim(s, s, w, h, 3) == doctest::Approx(1.0).epsilon(1e-12));
  std::vector<float> shifted(s.size());
  for (int c = 0; c < 3; ++c)
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) shifted[(size_t(c) * h + y) * w + x] = s[(size_t(c) * h + y) * w + std::max(0, x - 1)];
  const double sh = eval::ssim(s, shifted, w, h, 3);
  CHECK(sh < 0.95);
  CHECK(sh > 0.0);
  // Symmetric in its arguments.
  CHECK(eval::ssim(shifted, s, w, h, 3) == doctest::Approx(sh).epsilon(1e-12));
}

TEST_CASE("ssim: matches a direct (non-separable) double reference") {
  const int w = 23, h = 17;
  const auto a = testing::random_uniform(size_t(3) * w * h, 2, 0.0f, 1.0f);
  auto b = a;
  const auto noise = testing::random_normal(b.size(), 3, 0.1f);
  for (size_t i = 0; i < b.size(); ++i) b[i] = std::clamp(b[i] + noise[i], 0.0f, 1.0f);
  const double want = ssim_reference(a, b, w, h, 3), got = eval::ssim(a, b, w, h, 3);
  // Both in double; separable vs direct summation differ only by rounding: 1e-10 absolute.
  CHECK(std::abs(got - want) < 1e-10);
  CHECK(got < 0.99);
}

TEST_CASE("ssim: hard cases (constant images, too small, mismatched sizes)") {
  const int w = 16, h = 16;
  const std::vector<float> c1(size_t(w) * h, 0.3f), c2(size_t(w) * h, 0.6f), zero(size_t(w) * h, 0.0f);
  // Variances are 0: SSIM reduces to the luminance term (2 m1 m2 + C1) / (m1^2 + m2^2 + C1); finite.
  const double C1 = 1e-4;
  const double want = (2 * 0.3 * 0.6 + C1) / (0.09 + 0.36 + C1);
  CHECK(eval::ssim(c1, c2, w, h, 1) == doctest::Approx(want).epsilon(1e-6));
  CHECK(eval::ssim(zero, zero, w, h, 1) == doctest::Approx(1.0));
  CHECK(eval::ssim(c1, c1, w, h, 1) == doctest::Approx(1.0));
  CHECK_THROWS_AS(eval::ssim(std::vector<float>(100, 0.f), std::vector<float>(100, 0.f), 10, 10, 1), host::Error);
  CHECK_THROWS_AS(eval::ssim(c1, zero, w, h, 3), host::Error);
}
