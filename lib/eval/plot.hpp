// A minimal line plot as an image (no text: the numbers go in the report beside it). Each series is a
// polyline over x = 0 .. n-1, scaled into a frame with horizontal grid lines at tenths of the y range
// [0, y_max]; NaN values break the line. Colours are given by the caller and named in the report.
#pragma once
#include <array>
#include <string>
#include <vector>

#include "lib/io/image.hpp"

namespace stylerf::eval {

struct PlotSeries {
  std::string name;
  std::array<float, 3> colour{0, 0, 0};
  std::vector<double> values;
};

// y_max <= 0: the largest finite value x 1.1 (1 if there is none).
io::Image line_plot(const std::vector<PlotSeries>& series, int width = 640, int height = 360, double y_max = 0);

// Distinct colours for up to 8 series (then they repeat), with their names for the report.
std::array<float, 3> plot_colour(int i);
const char* plot_colour_name(int i);

}  // namespace stylerf::eval
