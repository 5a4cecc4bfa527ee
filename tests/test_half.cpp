// Half precision on the host (host/half.hpp) and F16 tensors: conversion against a double reference on the
// hard cases (signed zeros, subnormals, the largest half, ties to even, overflow, NaN), every one of the
// 65536 bit patterns round trip, and the raw byte spans of a tensor (write_bytes / read_bytes) refuse what
// lies outside it.
#include <doctest/doctest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <vector>

#include "host/half.hpp"
#include "host/tensor.hpp"
#include "tests/testing.hpp"

using namespace stylerf;
using host::half_to_float;
using host::float_to_half;

namespace {

// The half nearest to x by exhaustive search over the finite halves (ties to the even bit pattern), or
// infinity past the rounding boundary 65520: the definition of round-to-nearest-even, independent of the
// bit tricks in host/half.cpp.
uint16_t nearest_half(double x) {
  const uint16_t sign = std::signbit(x) ? 0x8000 : 0;
  const double a = std::fabs(x);
  if (a >= 65520.0) return uint16_t(sign | 0x7c00);
  uint16_t best = 0;
  double best_err = std::numeric_limits<double>::infinity();
  for (uint32_t b = 0; b < 0x7c00; ++b) {
    const double err = std::fabs(double(half_to_float(uint16_t(b))) - a);
    if (err < best_err || (err == best_err && (b & 1u) == 0)) best = uint16_t(b), best_err = err;
  }
  return uint16_t(sign | best);
}

}  // namespace

TEST_CASE("half: decoding against the formula, every finite bit pattern") {
  for (uint32_t b = 0; b < 0x10000; ++b) {
    const uint32_t e = (b >> 10) & 0x1f, m = b & 0x3ff;
    if (e == 0x1f) continue;
    const double mag = e == 0 ? std::ldexp(double(m), -24) : std::ldexp(1.0 + m / 1024.0, int(e) - 15);
    const double want = (b & 0x8000) ? -mag : mag;
    if (double(half_to_float(uint16_t(b))) != want) {
      CAPTURE(b);
      FAIL("half_to_float differs from the formula");
    }
  }
  CHECK(std::isinf(half_to_float(0x7c00)));
  CHECK(std::isnan(half_to_float(0x7e00)));
  CHECK(std::signbit(half_to_float(0x8000)));
}

TEST_CASE("half: every half survives half -> float -> half, NaNs stay NaN") {
  for (uint32_t b = 0; b < 0x10000; ++b) {
    const uint16_t h = uint16_t(b);
    const uint16_t back = float_to_half(half_to_float(h));
    const bool nan = ((b >> 10) & 0x1f) == 0x1f && (b & 0x3ff);
    if (nan ? !std::isnan(half_to_float(back)) : back != h) {
      CAPTURE(b);
      FAIL("round trip changed the value");
    }
  }
}

TEST_CASE("half: encoding rounds to nearest, ties to even, on the hard cases") {
  std::vector<double> xs = {0.0, -0.0, 1.0, -2.5, 65504.0, 65519.99, 65520.0, 1e6, -1e30,
                            std::ldexp(1.0, -14),                       // smallest normal
                            std::ldexp(1.0, -24),                       // smallest subnormal
                            std::ldexp(1.0, -25),                       // half of it: a tie, to 0
                            std::ldexp(1.5, -25),                       // above the tie: the subnormal
                            std::ldexp(3.0, -25),                       // tie between 1 and 2 units: to 2
                            std::ldexp(1023.5, -24),                    // tie at the top of the subnormals
                            1.0 + std::ldexp(1.0, -11),                 // tie between 1 and 1 + 2^-10: to 1
                            1.0 + 3 * std::ldexp(1.0, -11),             // tie: to the even 1 + 2^-9
                            2047.5, 2048.0 + 1.0, 0.1, 1.0 / 3.0, 123.456, 1e-8};
  for (double x : xs) {
    CAPTURE(x);
    const float f = float(x);
    CHECK(float_to_half(f) == nearest_half(double(f)));
  }
  CHECK(float_to_half(std::numeric_limits<float>::infinity()) == 0x7c00);
  CHECK(float_to_half(-std::numeric_limits<float>::infinity()) == 0xfc00);
  CHECK(std::isnan(half_to_float(float_to_half(std::nanf("")))));
  CHECK(float_to_half(std::numeric_limits<float>::denorm_min()) == 0);  // float subnormals underflow to 0
}

TEST_CASE("half: random floats over the whole range match the exhaustive reference") {
  std::vector<float> xs = testing::random_normal(300, 7);
  for (size_t i = 0; i < xs.size(); ++i) xs[i] = std::ldexp(xs[i], int(i % 40) - 28);  // 2^-28 .. 2^11 and beyond
  std::vector<uint16_t> bits(xs.size());
  host::floats_to_halves(xs.data(), xs.size(), bits.data());
  for (size_t i = 0; i < xs.size(); ++i) {
    CAPTURE(xs[i]);
    CHECK(bits[i] == nearest_half(double(xs[i])));
  }
}

TEST_CASE("F16 tensors: 2 bytes an element; byte spans read back what was written and refuse the outside") {
  host::Tensor t({3, 5}, host::DType::F16, "halves");
  CHECK(t.bytes() == 30);
  std::vector<uint16_t> in(15);
  for (size_t i = 0; i < in.size(); ++i) in[i] = float_to_half(float(i) * 0.5f);
  t.write_bytes(0, in.data(), 10);
  t.write_bytes(10, in.data() + 5, 20);
  std::vector<uint16_t> out(15);
  t.read_bytes(0, out.data(), 30);
  CHECK(out == in);
  uint16_t one = 0;
  t.read_bytes(28, &one, 2);
  CHECK(half_to_float(one) == 7.0f);
  testing::expect_error([&] { t.write_bytes(20, in.data(), 12); }, "bytes [20, 32) lie outside tensor");
  testing::expect_error([&] { t.read_bytes(31, &one, 0); }, "lie outside");
  testing::expect_error([&] { t.to_host(); }, "has dtype f16, not f32");
}
