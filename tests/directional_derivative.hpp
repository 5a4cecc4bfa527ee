// A gradient checked over a whole tensor at once: along random directions d, the directional derivative
// g.d against central differences (loss(x + h d) - loss(x - h d)) / 2h. Every entry takes part, so a wrong
// column block of a 1M-entry weight cannot hide between sampled entries.
#pragma once

#include <doctest/doctest.h>
#include <cmath>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>
#include "tests/testing.hpp"

namespace stylerf::testing {

// Directions are drawn from random_normal(x.size(), seed + k), k < directions. The tolerance scales with
// the root of the terms' squares, the natural size of a sum whose terms have random signs.
inline void check_random_directions(const std::string& what, const std::vector<float>& ours, const std::vector<double>& x,
                                    const std::function<double(const std::vector<double>&)>& loss, double h,
                                    double rtol, double atol, uint64_t seed, int directions = 3) {
  REQUIRE(ours.size() == x.size());
  for (int k = 0; k < directions; ++k) {
    const std::vector<double> d = to_double(random_normal(x.size(), seed + uint64_t(k)));
    std::vector<double> xp = x, xm = x;
    double along = 0, terms_sq = 0;
    for (size_t i = 0; i < x.size(); ++i) {
      xp[i] += h * d[i];
      xm[i] -= h * d[i];
      along += double(ours[i]) * d[i];
      terms_sq += double(ours[i]) * d[i] * double(ours[i]) * d[i];
    }
    const double numeric = (loss(xp) - loss(xm)) / (2 * h);
    const double tol = rtol * (std::abs(numeric) + std::sqrt(terms_sq)) + atol;
    INFO(what << ": along random direction " << k << ": ours " << along << ", central differences " << numeric);
    CHECK(std::abs(along - numeric) <= tol);
  }
}

}  // namespace stylerf::testing
