#include "lib/render/int_tensor.hpp"

#include <cstring>

#include "host/error.hpp"

namespace stylerf::render {

host::Tensor int_tensor_from_host(const std::vector<int32_t>& v, const std::string& what) {
  std::vector<float> bits(v.size());
  if (!v.empty()) std::memcpy(bits.data(), v.data(), v.size() * sizeof(int32_t));
  return host::Tensor::from_host(bits, {static_cast<int64_t>(v.size())}, what);
}

std::vector<int32_t> int_tensor_to_host(const host::Tensor& t) {
  const std::vector<float> bits = t.to_host();
  std::vector<int32_t> v(bits.size());
  if (!v.empty()) std::memcpy(v.data(), bits.data(), v.size() * sizeof(int32_t));
  return v;
}

int64_t exclusive_scan(const std::vector<int32_t>& counts, std::vector<int32_t>& offsets) {
  offsets.resize(counts.size());
  int64_t s = 0;
  for (size_t i = 0; i < counts.size(); ++i) {
    offsets[i] = static_cast<int32_t>(s);
    s += counts[i];
    if (s >= (int64_t(1) << 31)) throw host::Error("sample list longer than 2^31 entries");
  }
  return s;
}

}  // namespace stylerf::render
