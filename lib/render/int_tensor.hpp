// int32 arrays on the device, kept in float Tensors as raw bit patterns (Tensor is float-only; the kernels
// that use them declare the buffers int). Never run float ops on such a tensor.
#pragma once
#include <cstdint>
#include <vector>

#include "host/tensor.hpp"

namespace stylerf::render {

host::Tensor int_tensor_from_host(const std::vector<int32_t>& v, const std::string& what = "int tensor");
std::vector<int32_t> int_tensor_to_host(const host::Tensor& t);

// Exclusive prefix sum (deterministic, on the host); returns the total.
int64_t exclusive_scan(const std::vector<int32_t>& counts, std::vector<int32_t>& offsets);

}  // namespace stylerf::render
