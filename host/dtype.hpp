// Element types of device tensors. F32 is what every float op works on; I32 holds index arrays (ray
// offsets, counts, sample indices, view indices) that must survive bit-exact (a float cannot hold every int
// above 2^24); U8 holds byte grids (the alpha mask); F16 holds large read-only tables in half the memory
// (the stage-2 relu3_1 targets), as IEEE binary16 bits: kernels read them with vload_half (core OpenCL,
// no cl_khr_fp16 needed), the host converts with host/half.hpp. Kernels see them as float*, int*, uchar*
// and half*.
#pragma once
#include <cstddef>
#include <cstdint>
#include <type_traits>

namespace stylerf::host {

enum class DType { F32, I32, U8, F16 };

constexpr size_t dtype_size(DType d) { return d == DType::U8 ? 1 : d == DType::F16 ? 2 : 4; }
constexpr const char* dtype_name(DType d) {
  return d == DType::F32 ? "f32" : d == DType::I32 ? "i32" : d == DType::U8 ? "u8" : "f16";
}

// The DType of a host element type; F16 has none (its host form is raw bits: host/half.hpp).
template <class T>
constexpr bool has_dtype_v = std::is_same_v<T, float> || std::is_same_v<T, int32_t> || std::is_same_v<T, uint8_t>;
template <class T>
constexpr DType dtype_of() {
  static_assert(has_dtype_v<T>, "no device dtype for this host type");
  return std::is_same_v<T, float> ? DType::F32 : std::is_same_v<T, int32_t> ? DType::I32 : DType::U8;
}

}  // namespace stylerf::host
