// Kernel launch: sets arguments by type and enqueues on the runtime's queue, recording an event for
// per-kernel timing when profiling is on. Example:
//   launch("nn", "relu_forward", {n}, x, y, int(n));
// Global sizes are rounded up to a multiple of the local size; kernels guard their index. A launch without
// a local size gets auto_local_size_x's in dimension 0 (1 in the others, which stay exact), so every kernel
// must guard its dimension-0 index.
#pragma once
#include <CL/cl.h>

#include <array>
#include <cstdint>
#include <initializer_list>
#include <limits>
#include <string>
#include <type_traits>

#include "host/error.hpp"
#include "host/runtime.hpp"
#include "host/tensor.hpp"

namespace stylerf::host {

struct Range {
  std::array<size_t, 3> dims{1, 1, 1};
  cl_uint n = 1;
  Range(size_t x) : dims{x, 1, 1}, n(1) {}
  Range(size_t x, size_t y) : dims{x, y, 1}, n(2) {}
  Range(size_t x, size_t y, size_t z) : dims{x, y, z}, n(3) {}
};

namespace detail {
inline void set_arg(cl_kernel k, cl_uint i, const Tensor& t, const char* name) {
  cl_mem m = t.mem();
  check(clSetKernelArg(k, i, sizeof(cl_mem), &m), "clSetKernelArg", std::string(name) + " arg " + std::to_string(i));
}
inline void set_arg(cl_kernel k, cl_uint i, cl_mem m, const char* name) {
  check(clSetKernelArg(k, i, sizeof(cl_mem), &m), "clSetKernelArg", std::string(name) + " arg " + std::to_string(i));
}
template <class T, class = std::enable_if_t<std::is_arithmetic_v<T>>>
void set_arg(cl_kernel k, cl_uint i, T v, const char* name) {
  // Kernels take int and float only: convert so a size_t or double at the call site cannot mismatch.
  if constexpr (std::is_floating_point_v<T>) {
    float f = static_cast<float>(v);
    check(clSetKernelArg(k, i, sizeof(float), &f), "clSetKernelArg", std::string(name) + " arg " + std::to_string(i));
  } else {
    // A size past int's range would wrap silently and index the wrong memory: refuse it, named.
    if constexpr (std::is_signed_v<T>) {
      if (v < T(std::numeric_limits<cl_int>::min()) || v > T(std::numeric_limits<cl_int>::max()))
        throw Error(std::string("kernel ") + name + ": argument " + std::to_string(i) + " = " + std::to_string(v) +
                    " does not fit the kernel's 32-bit int");
    } else if (v > std::make_unsigned_t<cl_int>(std::numeric_limits<cl_int>::max())) {
      throw Error(std::string("kernel ") + name + ": argument " + std::to_string(i) + " = " + std::to_string(v) +
                  " does not fit the kernel's 32-bit int");
    }
    cl_int x = static_cast<cl_int>(v);
    check(clSetKernelArg(k, i, sizeof(cl_int), &x), "clSetKernelArg", std::string(name) + " arg " + std::to_string(i));
  }
}
}  // namespace detail

// The local size in dimension 0 of a launch that names none (the others get 1 and stay exact), from the
// global size in dimension 0, the product of the others, and the kernel's own limit: a power of two, at
// most 256; over a 1D range one of 256, 32 and 1 (eight groups or more), so that a kernel is compiled for
// few local sizes however its range changes.
size_t auto_local_size_x(size_t global_x, size_t groups_other, size_t kernel_max);

// Enqueues an already-fetched kernel. Range(0) as local: auto_local_size_x's.
void enqueue(cl_kernel k, const std::string& name, const Range& global, const Range& local);

template <class... Args>
void launch_with_local(const std::string& program, const std::string& kernel, const std::string& options,
                       const Range& global, const Range& local, const Args&... args) {
  cl_kernel k = Runtime::instance().kernel(program, kernel, options);
  cl_uint i = 0;
  (detail::set_arg(k, i++, args, kernel.c_str()), ...);
  enqueue(k, kernel, global, local);
}

// The common case: 1-3D global range, auto_local_size_x's local size, no build options.
template <class... Args>
void launch(const std::string& program, const std::string& kernel, const Range& global, const Args&... args) {
  launch_with_local(program, kernel, "", global, Range(0), args...);
}

}  // namespace stylerf::host
