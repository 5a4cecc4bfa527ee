#include "host/launch.hpp"

namespace stylerf::host {

void enqueue(cl_kernel k, const std::string& name, const Range& global, const Range& local) {
  Runtime& rt = Runtime::instance();
  const bool auto_local = local.dims[0] == 0;
  std::array<size_t, 3> g = global.dims;
  for (cl_uint d = 0; d < global.n; ++d) {
    if (g[d] == 0) return;  // nothing to do: an empty launch is not an error
    if (!auto_local && local.dims[d] > 0) g[d] = (g[d] + local.dims[d] - 1) / local.dims[d] * local.dims[d];
  }
  cl_event ev = nullptr;
  cl_event* evp = rt.profiling() ? &ev : nullptr;
  check(clEnqueueNDRangeKernel(rt.queue(), k, global.n, nullptr, g.data(), auto_local ? nullptr : local.dims.data(), 0,
                               nullptr, evp),
        "clEnqueueNDRangeKernel", "kernel " + name);
  if (evp) rt.record(name, ev);
}

}  // namespace stylerf::host
