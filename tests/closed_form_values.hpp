// Values given by a closed-form formula of (seed, index), the same in C++ and in the Python scripts that
// computed reference values from them with another implementation (tests/data/make_sict_dst_official.py):
// the reference file then needs no inputs or parameters, only outputs. Every value is formed exactly in
// double and rounded to float once, so both languages get the same bits.
#pragma once
#include <cmath>
#include <cstdint>
#include <vector>

namespace stylerf::testing::closed_form {

inline uint64_t splitmix64(uint64_t z) {
  z += 0x9E3779B97F4A7C15ull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

inline uint64_t bits(uint64_t seed, uint64_t i) { return splitmix64(splitmix64(seed) + i); }

// In [-half_width, half_width) on a grid of half_width / 2^23 (exact in float for a power-of-two half width).
inline double uniform_at(uint64_t seed, uint64_t i, double half_width) {
  const int64_t k = int64_t(bits(seed, i) >> 40) - (int64_t(1) << 23);
  return double(k) * (half_width / double(1 << 23));
}

inline std::vector<double> uniform(uint64_t seed, size_t n, double half_width) {
  std::vector<double> v(n);
  for (size_t i = 0; i < n; ++i) v[i] = uniform_at(seed, i, half_width);
  return v;
}

inline std::vector<float> to_float(const std::vector<double>& v) { return std::vector<float>(v.begin(), v.end()); }

inline std::vector<float> uniform_f(uint64_t seed, size_t n, double half_width) {
  return to_float(uniform(seed, n, half_width));
}

// [channels, n] (channel-major) features: per channel c, noise times 2^e_c (e_c in -2..1) plus an offset in
// [-4, 4), summed exactly in double and rounded once.
inline std::vector<float> features(uint64_t seed, int channels, int n) {
  const std::vector<double> noise = uniform(seed, size_t(channels) * n, 1.0), offset = uniform(seed + 2, channels, 4.0);
  std::vector<float> out(size_t(channels) * n);
  for (int c = 0; c < channels; ++c) {
    const int e = int(bits(seed + 1, uint64_t(c)) >> 62) - 2;
    for (int i = 0; i < n; ++i) out[size_t(c) * n + i] = float(std::ldexp(noise[size_t(c) * n + i], e) + offset[c]);
  }
  return out;
}

}  // namespace stylerf::testing::closed_form
