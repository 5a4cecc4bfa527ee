#include "lib/nn/reduce_path.hpp"

#include <cstdlib>

#include "host/error.hpp"
#include "host/runtime.hpp"

namespace stylerf::nn {

namespace {
// STYLERF_REDUCTION (auto | per-item | work-group) sets the starting choice: CTest runs the reduction
// suites a second time with work-group on the CPU device.
ReductionPath initial_path() {
  const char* env = std::getenv("STYLERF_REDUCTION");
  return env && *env ? parse_reduction_path(env) : ReductionPath::Auto;
}
ReductionPath g_path = initial_path();
}  // namespace

ReductionPath parse_reduction_path(const std::string& s) {
  if (s == "auto") return ReductionPath::Auto;
  if (s == "per-item") return ReductionPath::PerItem;
  if (s == "work-group") return ReductionPath::WorkGroup;
  throw host::Error("unknown reduction path '" + s + "' (auto, per-item, work-group)");
}

ReductionPath set_reduction_path(ReductionPath path) {
  const ReductionPath old = g_path;
  g_path = path;
  return old;
}

namespace detail {

bool group_reductions_by_default(const host::DeviceInfo& dev) {
  return !(dev.type & CL_DEVICE_TYPE_CPU) && dev.max_work_group >= size_t(kGroupLanes);
}

bool use_group_reductions() {
  const auto& dev = host::Runtime::instance().device();
  const bool fits = dev.max_work_group >= size_t(kGroupLanes);
  if (g_path == ReductionPath::WorkGroup) {
    if (!fits)
      throw host::Error("work-group reductions need groups of " + std::to_string(kGroupLanes) + " work-items; " +
                        dev.name + " allows " + std::to_string(dev.max_work_group));
    return true;
  }
  if (g_path == ReductionPath::PerItem) return false;
  return group_reductions_by_default(dev);
}

}  // namespace detail
}  // namespace stylerf::nn
