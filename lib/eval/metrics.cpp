#include "lib/eval/metrics.hpp"

#include <cmath>
#include <limits>
#include <string>

#include "host/error.hpp"

namespace stylerf::eval {

using host::Error;

static void check_same_size(const std::vector<float>& a, const std::vector<float>& b, const char* what) {
  if (a.size() != b.size())
    throw Error(std::string(what) + ": images have " + std::to_string(a.size()) + " and " + std::to_string(b.size()) +
                " values");
  if (a.empty()) throw Error(std::string(what) + ": empty images");
}

double mse(const std::vector<float>& a, const std::vector<float>& b) {
  check_same_size(a, b, "mse");
  double s = 0.0;
  for (size_t i = 0; i < a.size(); ++i) {
    const double d = double(a[i]) - double(b[i]);
    s += d * d;
  }
  return s / double(a.size());
}

double psnr_from_mse(double m) {
  if (!(m > 0.0)) return std::numeric_limits<double>::infinity();
  return -10.0 * std::log10(m);
}

double psnr(const std::vector<float>& a, const std::vector<float>& b) { return psnr_from_mse(mse(a, b)); }

// "Valid" separable Gaussian filtering of one plane: rows then columns.
static std::vector<double> filter_valid(const std::vector<double>& x, int w, int h, const std::vector<double>& k) {
  const int n = static_cast<int>(k.size());
  const int ow = w - n + 1, oh = h - n + 1;
  std::vector<double> tmp(size_t(h) * ow), out(size_t(oh) * ow);
  for (int y = 0; y < h; ++y)
    for (int x0 = 0; x0 < ow; ++x0) {
      double s = 0.0;
      for (int i = 0; i < n; ++i) s += k[i] * x[size_t(y) * w + x0 + i];
      tmp[size_t(y) * ow + x0] = s;
    }
  for (int y0 = 0; y0 < oh; ++y0)
    for (int x0 = 0; x0 < ow; ++x0) {
      double s = 0.0;
      for (int i = 0; i < n; ++i) s += k[i] * tmp[size_t(y0 + i) * ow + x0];
      out[size_t(y0) * ow + x0] = s;
    }
  return out;
}

double ssim(const std::vector<float>& a, const std::vector<float>& b, int width, int height, int channels,
            const SsimOptions& opt) {
  check_same_size(a, b, "ssim");
  if (size_t(width) * height * channels != a.size())
    throw Error("ssim: " + std::to_string(a.size()) + " values do not match " + std::to_string(channels) + "x" +
                std::to_string(height) + "x" + std::to_string(width));
  if (width < opt.window || height < opt.window)
    throw Error("ssim: image " + std::to_string(width) + "x" + std::to_string(height) + " is smaller than the " +
                std::to_string(opt.window) + "x" + std::to_string(opt.window) + " window");
  std::vector<double> k(opt.window);
  double ks = 0.0;
  const double half = (opt.window - 1) / 2.0;
  for (int i = 0; i < opt.window; ++i) {
    const double d = i - half;
    k[i] = std::exp(-0.5 * d * d / (opt.sigma * opt.sigma));
    ks += k[i];
  }
  for (double& v : k) v /= ks;
  const double c1 = std::pow(opt.k1 * opt.data_range, 2), c2 = std::pow(opt.k2 * opt.data_range, 2);
  const size_t plane = size_t(width) * height;
  double total = 0.0;
  size_t count = 0;
  for (int c = 0; c < channels; ++c) {
    std::vector<double> x(plane), y(plane), xx(plane), yy(plane), xy(plane);
    for (size_t i = 0; i < plane; ++i) {
      x[i] = a[c * plane + i];
      y[i] = b[c * plane + i];
      xx[i] = x[i] * x[i];
      yy[i] = y[i] * y[i];
      xy[i] = x[i] * y[i];
    }
    const auto mx = filter_valid(x, width, height, k), my = filter_valid(y, width, height, k);
    const auto sxx = filter_valid(xx, width, height, k), syy = filter_valid(yy, width, height, k),
               sxy = filter_valid(xy, width, height, k);
    for (size_t i = 0; i < mx.size(); ++i) {
      // Clamp the variances: rounding can make E[x^2] - E[x]^2 slightly negative on flat regions.
      const double vx = std::max(0.0, sxx[i] - mx[i] * mx[i]), vy = std::max(0.0, syy[i] - my[i] * my[i]);
      const double cov = sxy[i] - mx[i] * my[i];
      const double num = (2 * mx[i] * my[i] + c1) * (2 * cov + c2);
      const double den = (mx[i] * mx[i] + my[i] * my[i] + c1) * (vx + vy + c2);
      total += num / den;
      ++count;
    }
  }
  return total / double(count);
}

double ssim(const io::Image& a, const io::Image& b, const SsimOptions& opt) {
  if (a.width != b.width || a.height != b.height)
    throw Error("ssim: images are " + std::to_string(a.width) + "x" + std::to_string(a.height) + " and " +
                std::to_string(b.width) + "x" + std::to_string(b.height));
  return ssim(a.data, b.data, a.width, a.height, 3, opt);
}

std::vector<float> interleaved_to_planar(const std::vector<float>& hwc, int w, int h) {
  std::vector<float> out(hwc.size());
  const size_t plane = size_t(w) * h;
  for (size_t i = 0; i < plane; ++i)
    for (int c = 0; c < 3; ++c) out[c * plane + i] = hwc[3 * i + c];
  return out;
}

}  // namespace stylerf::eval
