#include "lib/render/scan.hpp"

#include "host/error.hpp"

namespace stylerf::render {

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
