#include "lib/eval/finite_image.hpp"

#include <cmath>

namespace stylerf::eval {

std::string non_finite_at(const io::Image& im) {
  const size_t plane = size_t(im.width) * size_t(im.height);
  if (plane == 0) return "";
  for (size_t k = 0; k < im.data.size(); ++k)
    if (!std::isfinite(im.data[k]))
      return std::string(std::isnan(im.data[k]) ? "a NaN" : "an infinite") + " value at pixel " +
             std::to_string((k % plane) % size_t(im.width)) + "," + std::to_string((k % plane) / size_t(im.width)) +
             ", channel " + std::to_string(k / plane);
  return "";
}

}  // namespace stylerf::eval
