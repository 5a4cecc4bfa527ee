#include "host/half.hpp"

#include <cstring>

namespace stylerf::host {

uint16_t float_to_half(float f) {
  uint32_t x = 0;
  std::memcpy(&x, &f, sizeof x);
  const uint32_t sign = (x >> 16) & 0x8000u;
  const uint32_t abs = x & 0x7fffffffu;
  if (abs >= 0x7f800000u)  // infinity, or NaN (kept a quiet NaN: a payload may not survive 13 dropped bits)
    return uint16_t(sign | 0x7c00u | (abs > 0x7f800000u ? 0x0200u : 0u));
  if (abs >= 0x477ff000u) return uint16_t(sign | 0x7c00u);  // rounds past 65504
  if (abs < 0x38800000u) {  // below the smallest normal half (2^-14): subnormal or zero
    if (abs < 0x33000000u) return uint16_t(sign);  // below half the smallest subnormal (2^-25): zero
    // The significand with its hidden bit, shifted down to units of 2^-24, rounded to nearest even.
    const uint32_t exp = abs >> 23;
    const uint32_t mant = (abs & 0x7fffffu) | 0x800000u;
    const uint32_t shift = 126u - exp;  // 14 + (127 - exp) - 1 - 9 ... = bits dropped to reach 2^-24 units
    const uint32_t kept = mant >> shift;
    const uint32_t rest = mant & ((1u << shift) - 1u);
    const uint32_t half_way = 1u << (shift - 1u);
    const uint32_t rounded = kept + ((rest > half_way || (rest == half_way && (kept & 1u))) ? 1u : 0u);
    return uint16_t(sign | rounded);  // a carry into bit 10 gives the smallest normal: still correct
  }
  // Normal: rebias the exponent (127 -> 15) and drop 13 significand bits, rounding to nearest even. A carry
  // out of the significand moves into the exponent, which is the correct result (up to infinity, above).
  const uint32_t base = abs - 0x38000000u;  // exponent - 112 in place
  const uint32_t kept = base >> 13;
  const uint32_t rest = base & 0x1fffu;
  const uint32_t rounded = kept + ((rest > 0x1000u || (rest == 0x1000u && (kept & 1u))) ? 1u : 0u);
  return uint16_t(sign | rounded);
}

float half_to_float(uint16_t h) {
  const uint32_t sign = uint32_t(h & 0x8000u) << 16;
  const uint32_t exp = (h >> 10) & 0x1fu;
  uint32_t mant = h & 0x3ffu;
  uint32_t x = 0;
  if (exp == 0x1fu) {
    x = sign | 0x7f800000u | (mant << 13);  // infinity or NaN
  } else if (exp != 0) {
    x = sign | ((exp + 112u) << 23) | (mant << 13);
  } else if (mant == 0) {
    x = sign;  // signed zero
  } else {  // subnormal: normalise
    int e = -1;
    do {
      mant <<= 1;
      ++e;
    } while (!(mant & 0x400u));
    x = sign | (uint32_t(112 - e) << 23) | ((mant & 0x3ffu) << 13);
  }
  float f = 0;
  std::memcpy(&f, &x, sizeof f);
  return f;
}

void floats_to_halves(const float* in, size_t n, uint16_t* out) {
  for (size_t i = 0; i < n; ++i) out[i] = float_to_half(in[i]);
}

void halves_to_floats(const uint16_t* in, size_t n, float* out) {
  for (size_t i = 0; i < n; ++i) out[i] = half_to_float(in[i]);
}

}  // namespace stylerf::host
