#include "host/launch.hpp"

#include <unordered_map>

namespace stylerf::host {

size_t auto_local_size_x(size_t global_x, size_t groups_other, size_t kernel_max) {
  // Few sizes (PoCL compiles each one), and enough work-groups for both CPU cores and a GPU's units.
  size_t cap = 256;
  while (cap > 1 && cap > kernel_max) cap /= 2;
  if (groups_other >= 8) {
    // The other dimensions give the groups: one group spans dimension 0 (its extent, rounded up to a
    // power of two), as the driver would; such a kernel's dimension 0 is a fixed extent (channels, width).
    size_t l = 1;
    while (l < global_x && l < cap) l *= 2;
    return l;
  }
  // A 1D range (point and ray counts, which change every step): 256, 32 or 1 work-items a group, whichever
  // leaves eight groups or more: three sizes a kernel at most.
  for (size_t l : {size_t(256), size_t(32)})
    if (l <= cap && global_x >= 8 * l) return l;
  return 1;
}

namespace {
// CL_KERNEL_WORK_GROUP_SIZE of each kernel object, asked once (a GPU kernel heavy in registers may allow
// fewer than 256 work-items).
size_t kernel_max_group(cl_kernel k, const std::string& name) {
  static std::unordered_map<cl_kernel, size_t> known;
  auto it = known.find(k);
  if (it != known.end()) return it->second;
  size_t most = 0;
  check(clGetKernelWorkGroupInfo(k, Runtime::instance().device().id, CL_KERNEL_WORK_GROUP_SIZE, sizeof(most), &most,
                                 nullptr),
        "clGetKernelWorkGroupInfo", "kernel " + name);
  known.emplace(k, most);
  return most;
}
}  // namespace

void enqueue(cl_kernel k, const std::string& name, const Range& global, const Range& local) {
  Runtime& rt = Runtime::instance();
  std::array<size_t, 3> g = global.dims, l = local.dims;
  for (cl_uint d = 0; d < global.n; ++d)
    if (g[d] == 0) return;  // nothing to do: an empty launch is not an error
  if (l[0] == 0) {
    // Never the driver's choice: PoCL picks a local size from the global one (often the whole range, in one
    // work-group on one core) and compiles the kernel anew for every local size it meets, ~0.25 s each on
    // this CPU; point and ray counts change every step and frame, so a 30-step style run spent 74 of its
    // 105 s compiling (docs/design.md). Only dimension 0 is padded: every kernel guards it.
    l = {auto_local_size_x(g[0], g[1] * g[2], kernel_max_group(k, name)), 1, 1};
  }
  for (cl_uint d = 0; d < global.n; ++d)
    if (l[d] > 0) g[d] = (g[d] + l[d] - 1) / l[d] * l[d];
  cl_event ev = nullptr;
  cl_event* evp = rt.profiling() ? &ev : nullptr;
  check(clEnqueueNDRangeKernel(rt.queue(), k, global.n, nullptr, g.data(), l.data(), 0, nullptr, evp),
        "clEnqueueNDRangeKernel", "kernel " + name);
  if (evp) rt.record(name, ev);
}

}  // namespace stylerf::host
