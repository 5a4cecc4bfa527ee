#include "lib/eval/plot.hpp"

#include <algorithm>
#include <cmath>

#include "host/error.hpp"

namespace stylerf::eval {

namespace {

constexpr int kMargin = 24;

void put(io::Image& img, int x, int y, const std::array<float, 3>& c) {
  if (x < 0 || y < 0 || x >= img.width || y >= img.height) return;
  for (int ch = 0; ch < 3; ++ch) img.at(ch, y, x) = c[ch];
}

// A 2-pixel-wide segment (Bresenham over the longer axis).
void segment(io::Image& img, double x0, double y0, double x1, double y1, const std::array<float, 3>& c) {
  const int steps = int(std::ceil(std::max(std::abs(x1 - x0), std::abs(y1 - y0)))) + 1;
  for (int i = 0; i <= steps; ++i) {
    const double f = double(i) / steps;
    const int x = int(std::lround(x0 + f * (x1 - x0))), y = int(std::lround(y0 + f * (y1 - y0)));
    put(img, x, y, c);
    put(img, x + 1, y, c);
    put(img, x, y + 1, c);
  }
}

}  // namespace

std::array<float, 3> plot_colour(int i) {
  static const std::array<float, 3> kColours[8] = {{0.0f, 0.0f, 0.0f}, {0.85f, 0.2f, 0.1f}, {0.1f, 0.35f, 0.85f},
                                                  {0.1f, 0.6f, 0.2f},  {0.8f, 0.5f, 0.0f}, {0.55f, 0.2f, 0.7f},
                                                  {0.0f, 0.6f, 0.65f}, {0.5f, 0.5f, 0.5f}};
  return kColours[((i % 8) + 8) % 8];
}

const char* plot_colour_name(int i) {
  static const char* kNames[8] = {"black", "red", "blue", "green", "orange", "purple", "teal", "grey"};
  return kNames[((i % 8) + 8) % 8];
}

io::Image line_plot(const std::vector<PlotSeries>& series, int width, int height, double y_max) {
  if (width < 4 * kMargin || height < 4 * kMargin)
    throw host::Error("line_plot: " + std::to_string(width) + "x" + std::to_string(height) + " is too small");
  size_t n = 0;
  double top = 0;
  for (const auto& s : series) {
    n = std::max(n, s.values.size());
    for (double v : s.values)
      if (std::isfinite(v)) top = std::max(top, v);
  }
  if (y_max <= 0) y_max = top > 0 ? top * 1.1 : 1.0;
  io::Image img;
  img.width = width;
  img.height = height;
  img.data.assign(size_t(3) * width * height, 1.0f);
  const double x_lo = kMargin, x_hi = width - kMargin, y_lo = height - kMargin, y_hi = kMargin;
  const std::array<float, 3> grid{0.88f, 0.88f, 0.88f}, axis{0.3f, 0.3f, 0.3f};
  for (int g = 1; g <= 10; ++g) {
    const double y = y_lo + (y_hi - y_lo) * g / 10.0;
    segment(img, x_lo, y, x_hi, y, grid);
  }
  segment(img, x_lo, y_lo, x_hi, y_lo, axis);
  segment(img, x_lo, y_lo, x_lo, y_hi, axis);
  auto px = [&](size_t i) { return n > 1 ? x_lo + (x_hi - x_lo) * double(i) / double(n - 1) : (x_lo + x_hi) / 2; };
  auto py = [&](double v) { return y_lo + (y_hi - y_lo) * std::min(1.0, std::max(0.0, v / y_max)); };
  for (size_t i = 0; i < n; ++i) segment(img, px(i), y_lo, px(i), y_lo + 4, axis);  // ticks
  for (const auto& s : series) {
    for (size_t i = 0; i + 1 < s.values.size(); ++i)
      if (std::isfinite(s.values[i]) && std::isfinite(s.values[i + 1]))
        segment(img, px(i), py(s.values[i]), px(i + 1), py(s.values[i + 1]), s.colour);
    for (size_t i = 0; i < s.values.size(); ++i)  // a dot per point, so single points show
      if (std::isfinite(s.values[i]))
        for (int dy = -2; dy <= 2; ++dy)
          for (int dx = -2; dx <= 2; ++dx) put(img, int(std::lround(px(i))) + dx, int(std::lround(py(s.values[i]))) + dy, s.colour);
  }
  return img;
}

}  // namespace stylerf::eval
