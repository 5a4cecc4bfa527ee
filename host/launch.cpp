#include "host/launch.hpp"

#include <unordered_map>

namespace stylerf::host {

size_t auto_local_size_x(size_t global_x, size_t kernel_max) {
  // Aim at 8 or more work-groups (both CPU cores busy, and a GPU's units), at most 256 work-items each,
  // and only powers of two: a kernel is compiled for at most 9 local sizes whatever its global sizes.
  size_t cap = 256;
  while (cap > 1 && cap > kernel_max) cap /= 2;
  const size_t target = (global_x + 7) / 8;
  size_t l = 1;
  while (l * 2 <= target && l * 2 <= cap) l *= 2;
  return l;
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
    // 105 s compiling (docs/experiments.md). Only dimension 0 is padded: every kernel guards it.
    l = {auto_local_size_x(g[0], kernel_max_group(k, name)), 1, 1};
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
