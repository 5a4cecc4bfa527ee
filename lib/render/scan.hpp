// The exclusive prefix sum that turns per-ray counts into offsets of a compacted list (march, keep_by_weight).
// Done on the host: the counts are read back anyway to size the list, and a serial sum is deterministic.
#pragma once
#include <cstdint>
#include <vector>

namespace stylerf::render {

// offsets[i] = counts[0] + ... + counts[i-1]; returns the total. Throws when it would not fit in int32 (the
// kernels index the list with ints).
int64_t exclusive_scan(const std::vector<int32_t>& counts, std::vector<int32_t>& offsets);

}  // namespace stylerf::render
