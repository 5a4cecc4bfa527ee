// A line plot that can be read on its own: an SVG with a title, both axes labelled with their units,
// ticks at round values, a light grid and a legend naming each line by its colour. Each series is a
// polyline over x = 0 .. n-1; NaN values break the line (each finite point also gets a dot, so single
// points show).
#pragma once
#include <array>
#include <string>
#include <vector>

namespace stylerf::eval {

struct PlotSeries {
  std::string name;
  std::array<float, 3> colour{0, 0, 0};
  std::vector<double> values;
};

struct PlotLabels {
  std::string title, x_label, y_label;  // labels name the units, e.g. "RMSE (RGB in [0, 1])"
  double x_first = 0;                   // the x value of index 0 (e.g. 1 for "frame pair 1")
};

// y axis from 0 to y_max (y_max <= 0: the largest finite value x 1.1, 1 if there is none), rounded up
// to the last tick.
std::string line_plot_svg(const std::vector<PlotSeries>& series, const PlotLabels& labels, int width = 720,
                          int height = 400, double y_max = 0);

// Distinct colours for up to 8 series (then they repeat), with their names for the report.
std::array<float, 3> plot_colour(int i);
const char* plot_colour_name(int i);

}  // namespace stylerf::eval
