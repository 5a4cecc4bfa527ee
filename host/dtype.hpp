// Element types of device tensors. F32 is what every float op works on; I32 holds index arrays (ray
// offsets, counts, sample indices, view indices) that must survive bit-exact (a float cannot hold every int
// above 2^24); U8 holds byte grids (the alpha mask). Kernels see them as float*, int* and uchar*.
#pragma once
#include <cstddef>
#include <cstdint>
#include <type_traits>

namespace stylerf::host {

enum class DType { F32, I32, U8 };

constexpr size_t dtype_size(DType d) { return d == DType::U8 ? 1 : 4; }
constexpr const char* dtype_name(DType d) { return d == DType::F32 ? "f32" : d == DType::I32 ? "i32" : "u8"; }

// The DType of a host element type; only the three above have one.
template <class T>
constexpr bool has_dtype_v = std::is_same_v<T, float> || std::is_same_v<T, int32_t> || std::is_same_v<T, uint8_t>;
template <class T>
constexpr DType dtype_of() {
  static_assert(has_dtype_v<T>, "no device dtype for this host type");
  return std::is_same_v<T, float> ? DType::F32 : std::is_same_v<T, int32_t> ? DType::I32 : DType::U8;
}

}  // namespace stylerf::host
