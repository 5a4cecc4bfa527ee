#include "lib/eval/plot.hpp"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>

#include "host/error.hpp"

namespace stylerf::eval {
namespace {

// Ticks at 1, 2 or 5 x 10^k, about `target` of them from 0 to past `top`.
double tick_step(double top, int target) {
  const double raw = top / target, mag = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0, 10.0})
    if (m * mag >= raw) return m * mag;
  return 10.0 * mag;
}

std::string number(double v, double step) {
  std::ostringstream o;
  const int digits = std::max(0, int(-std::floor(std::log10(step) + 1e-9)));
  o << std::fixed << std::setprecision(digits) << v;
  return o.str();
}

std::string rgb(const std::array<float, 3>& c) {
  std::ostringstream o;
  o << "rgb(" << int(std::lround(255 * c[0])) << "," << int(std::lround(255 * c[1])) << ","
    << int(std::lround(255 * c[2])) << ")";
  return o.str();
}

std::string escape(const std::string& s) {
  std::string o;
  for (char c : s) o += c == '<' ? "&lt;" : c == '>' ? "&gt;" : c == '&' ? "&amp;" : std::string(1, c);
  return o;
}

}  // namespace

std::string line_plot_svg(const std::vector<PlotSeries>& series, const PlotLabels& labels, int width, int height,
                          double y_max) {
  constexpr int kLeft = 70, kRight = 20, kTop = 40, kBottom = 55, kLegendRow = 18;
  const int legend_h = kLegendRow * int(series.size());
  if (width < kLeft + kRight + 100 || height < kTop + kBottom + legend_h + 60)
    throw host::Error("line_plot_svg: " + std::to_string(width) + "x" + std::to_string(height) + " is too small for " +
                      std::to_string(series.size()) + " series");
  size_t n = 0;
  double top = 0;
  for (const auto& s : series) {
    n = std::max(n, s.values.size());
    for (double v : s.values)
      if (std::isfinite(v)) top = std::max(top, v);
  }
  if (y_max <= 0) y_max = top > 0 ? top * 1.1 : 1.0;
  const double ystep = tick_step(y_max, 5);
  y_max = std::ceil(y_max / ystep - 1e-9) * ystep;
  const double x0 = kLeft, x1 = width - kRight, y0 = height - kBottom - legend_h, y1 = kTop;
  auto px = [&](size_t i) { return n > 1 ? x0 + (x1 - x0) * double(i) / double(n - 1) : (x0 + x1) / 2; };
  auto py = [&](double v) { return y0 + (y1 - y0) * std::clamp(v / y_max, 0.0, 1.0); };
  std::ostringstream o;
  o << std::fixed << std::setprecision(1);
  o << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << width << "\" height=\"" << height
    << "\" font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  o << "<text x=\"" << width / 2 << "\" y=\"22\" text-anchor=\"middle\" font-size=\"15\">" << escape(labels.title)
    << "</text>\n";
  for (double v = 0; v <= y_max + ystep * 1e-6; v += ystep) {  // y ticks and grid
    o << "<line x1=\"" << x0 << "\" y1=\"" << py(v) << "\" x2=\"" << x1 << "\" y2=\"" << py(v)
      << "\" stroke=\"#ddd\"/>\n<text x=\"" << x0 - 6 << "\" y=\"" << py(v) + 4 << "\" text-anchor=\"end\">"
      << number(v, ystep) << "</text>\n";
  }
  const double xstep = n > 1 ? tick_step(double(n - 1), 8) : 1;
  for (double i = 0; i < double(std::max<size_t>(n, 1)); i += std::max(1.0, xstep)) {  // x ticks
    const double x = px(size_t(i));
    o << "<line x1=\"" << x << "\" y1=\"" << y0 << "\" x2=\"" << x << "\" y2=\"" << y0 + 5 << "\" stroke=\"#444\"/>\n"
      << "<text x=\"" << x << "\" y=\"" << y0 + 18 << "\" text-anchor=\"middle\">"
      << number(labels.x_first + i, 1) << "</text>\n";
  }
  o << "<line x1=\"" << x0 << "\" y1=\"" << y0 << "\" x2=\"" << x1 << "\" y2=\"" << y0 << "\" stroke=\"#444\"/>\n"
    << "<line x1=\"" << x0 << "\" y1=\"" << y0 << "\" x2=\"" << x0 << "\" y2=\"" << y1 << "\" stroke=\"#444\"/>\n"
    << "<text x=\"" << (x0 + x1) / 2 << "\" y=\"" << y0 + 38 << "\" text-anchor=\"middle\">" << escape(labels.x_label)
    << "</text>\n<text transform=\"translate(16," << (y0 + y1) / 2 << ") rotate(-90)\" text-anchor=\"middle\">"
    << escape(labels.y_label) << "</text>\n";
  for (size_t si = 0; si < series.size(); ++si) {
    const auto& s = series[si];
    const std::string c = rgb(s.colour);
    std::string points;
    auto flush = [&] {
      if (!points.empty())
        o << "<polyline fill=\"none\" stroke=\"" << c << "\" stroke-width=\"2\" points=\"" << points << "\"/>\n";
      points.clear();
    };
    for (size_t i = 0; i < s.values.size(); ++i) {
      if (!std::isfinite(s.values[i])) {
        flush();
        continue;
      }
      std::ostringstream pt;
      pt << std::fixed << std::setprecision(1) << px(i) << "," << py(s.values[i]) << " ";
      points += pt.str();
      o << "<circle cx=\"" << px(i) << "\" cy=\"" << py(s.values[i]) << "\" r=\"2.5\" fill=\"" << c << "\"/>\n";
    }
    flush();
    const double ly = height - kBottom - legend_h + 52 + kLegendRow * double(si);  // the legend, under the axis
    o << "<line x1=\"" << x0 << "\" y1=\"" << ly << "\" x2=\"" << x0 + 24 << "\" y2=\"" << ly << "\" stroke=\"" << c
      << "\" stroke-width=\"3\"/>\n<text x=\"" << x0 + 30 << "\" y=\"" << ly + 4 << "\">" << escape(s.name)
      << "</text>\n";
  }
  o << "</svg>\n";
  return o.str();
}

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

}  // namespace stylerf::eval
