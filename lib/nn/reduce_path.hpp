// Which first stage the reductions use (sums, MSE, channel statistics, the normalisation backward):
// per-work-item runs of contiguous floats (kernels/reduce.cl, loss.cl, norm.cl: best on CPU devices,
// whose work-items stream with vector loads) or one work-group per chunk with lanes reading neighbouring
// floats and a __local tree (kernels/group_reduce.cl: for GPUs). Both are deterministic; they differ
// only in rounding order. Auto chooses by device type: work-groups on devices that are not CPUs and allow
// groups of kGroupLanes.
#pragma once
#include <string>

#include "host/device.hpp"
#include "host/launch.hpp"

namespace stylerf::nn {

enum class ReductionPath { Auto, PerItem, WorkGroup };
ReductionPath parse_reduction_path(const std::string& s);  // "auto" | "per-item" | "work-group"
// Process-wide choice (tests and bench compare the two paths on one device); returns the previous one.
ReductionPath set_reduction_path(ReductionPath path);

namespace detail {

constexpr int kGroupLanes = 256;  // WG in kernels/group_reduce.cl
// True when the reductions take the work-group path on the current device (the process-wide choice), or
// by default on `dev`.
bool use_group_reductions();
bool group_reductions_by_default(const host::DeviceInfo& dev);

// The program of the group_reduce.cl kernels (built after norm.cl, whose finishing code they share).
constexpr const char* kGroupReduceProgram = "norm+group_reduce";
// Launches a group_reduce.cl kernel over `groups` x `rows` work-groups of kGroupLanes lanes.
template <class... Args>
void launch_group_reduce(const char* kernel, size_t groups, size_t rows, const Args&... args) {
  host::launch_with_local(kGroupReduceProgram, kernel, "", host::Range(groups * kGroupLanes, rows),
                          host::Range(size_t(kGroupLanes), 1), args...);
}

}  // namespace detail
}  // namespace stylerf::nn
