#pragma once
// Seeded random inputs for the benches: the same seed gives the same values on every run and machine
// (std::mt19937's sequence is fixed by the standard; the distributions' are libstdc++'s).

#include <cstddef>
#include <cstdint>
#include <random>
#include <vector>

namespace stylerf::bench {

inline std::vector<float> uniform_floats(size_t n, uint32_t seed, float lo, float hi) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(lo, hi);
  std::vector<float> v(n);
  for (float& x : v) x = u(rng);
  return v;
}

inline std::vector<float> normal_floats(size_t n, uint32_t seed, float stddev = 1.0f) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> d(0.0f, stddev);
  std::vector<float> v(n);
  for (float& x : v) x = d(rng);
  return v;
}

}  // namespace stylerf::bench
