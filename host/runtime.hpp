// The process-wide OpenCL runtime: one device, one context, one in-order queue with profiling.
//
// Kernels come from kernels/<program>.cl, embedded at build time; with STYLERF_KERNEL_DIR set they are
// read from that directory instead (edit a kernel, rerun, no rebuild). Programs are built once per
// (program, options) pair and kept; compiled binaries persist across processes:
//   - PoCL keeps its own cache in POCL_CACHE_DIR, which we point at ~/.cache/stylerf/pocl when unset;
//   - other drivers: binaries in ~/.cache/stylerf/programs, keyed by a hash of source, options,
//     device name and driver version.
#pragma once
#include <CL/cl.h>

#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "host/device.hpp"

namespace stylerf::host {

// A program of kernels/ and the build options it is launched with (one build each).
struct ProgramBuild {
  std::string program, options;
};

// Per-kernel time totals gathered while profiling is on.
struct KernelTiming {
  std::string kernel;
  int launches = 0;
  double total_ms = 0.0;
};

// The buffer pool's default cap for a device of `global_mem_bytes`. CPU devices: a quarter of their memory,
// but at least half of it up to 4 GiB. A stage-3 fern step frees ~2 GiB of per-sample tensors (x, q/k/v,
// their gradients) that the next step asks for again; a cap below that hands them back to the driver, and
// re-faulting their pages cost 20-25% of the step on PoCL. PoCL may report far less than the host's RAM
// (6.5 GiB of 24 seen here), so a quarter alone is not enough. Other devices: a quarter, at most 1 GiB:
// GPU drivers commit memory lazily, so an over-full pool would fail at a later enqueue rather than at
// clCreateBuffer, where allocate() trims the pool and retries.
size_t default_pool_cap_bytes(bool cpu_device, size_t global_mem_bytes);

class Runtime {
 public:
  // Initialises the process-wide runtime on the device named by spec (see choose_device). Calling it
  // again with a different device throws; the first call of instance() initialises with spec "".
  static Runtime& init(const std::string& device_spec = "");
  static Runtime& instance();
  static bool initialised();
  // Drains the queue and releases everything. Call it before main returns (the CLI, the tests and the
  // embedding example do): PoCL compiles kernels lazily on its worker threads, and a compile still
  // running while the process exits can touch LLVM objects that exit has already destroyed. Without a
  // call, an atexit handler does the same, which is safe only if the queue is already drained.
  static void shutdown();

  const DeviceInfo& device() const { return device_; }
  cl_context context() const { return context_; }
  cl_command_queue queue() const { return queue_; }
  cl_command_queue* queue_ptr() { return &queue_; }

  // A kernel of kernels/<program>.cl built with the given options (e.g. "-DTILE=8"). Cached.
  cl_kernel kernel(const std::string& program, const std::string& name, const std::string& options = "");
  // Builds the program now unless it is built already (kernel() builds at first use): a training stage
  // builds every program it launches before its clock starts. PoCL still generates each kernel's code for
  // a work-group size at its first launch (~50 ms a kernel measured here), which only a launch can do.
  void build(const ProgramBuild& p);
  // How many (program, options) builds this process holds: tests check that a stage's steps add none.
  size_t programs_built() const { return programs_.size(); }
  // The source of kernels/<program>.cl (embedded, or from STYLERF_KERNEL_DIR); "a+b" is a.cl then b.cl.
  std::string program_source(const std::string& program) const;

  // Allocates a device buffer. Throws an Error naming `what`, the bytes asked for and the device's
  // limits when the request exceeds them or the driver refuses it.
  cl_mem allocate(size_t bytes, const std::string& what);
  // Returns a buffer from allocate() for reuse. Freed buffers are kept (up to a cap: default_pool_cap_bytes,
  // or STYLERF_POOL_MIB) and handed out again for requests of the same rounded size or up to half of it:
  // a fresh buffer costs first-touch page faults on a CPU device and an allocation on a GPU, and training
  // loops allocate about the same shapes every step. A pooled buffer that no request has taken for
  // kPoolIdleAllocations allocations is released, so sizes a loop has moved past do not hold memory, and
  // a fresh buffer of 1 MiB or more releases the pooled ones of half its size up to its own, which it
  // will serve from then on.
  // The in-order queue makes reuse safe: commands using the old owner finish before those of the new one.
  // A buffer over a quarter of the cap is released, not pooled: a one-off such as the stage-2 target maps.
  void release(cl_mem mem, size_t bytes);
  static constexpr uint64_t kPoolIdleAllocations = 2048;
  size_t pool_cap_bytes() const { return pool_cap_bytes_; }
  void trim_buffer_pool();  // frees every cached buffer
  size_t pooled_bytes() const { return pooled_bytes_; }
  // Bytes held by live tensors (allocate() minus release(), as requested, pool rounding aside) and their
  // high-water mark since the last reset_peak(): what benches report as an algorithm's peak memory.
  size_t live_bytes() const { return live_bytes_; }
  size_t peak_live_bytes() const { return peak_live_bytes_; }
  void reset_peak() { peak_live_bytes_ = live_bytes_; }

  void finish();

  // Profiling: while on, every launch() records an event; timings() waits for them and sums per kernel.
  // STYLERF_PROFILE=1 switches it on at start.
  void set_profiling(bool on) { profiling_ = on; }
  bool profiling() const { return profiling_; }
  void record(const std::string& kernel_name, cl_event event);
  // Work done on the host between commands (the host-BLAS GEMM engine): added to the totals as is.
  void record_host(const std::string& name, double ms);
  std::vector<KernelTiming> timings();
  void reset_timings();
  std::string timing_report();

  ~Runtime();
  Runtime(const Runtime&) = delete;
  Runtime& operator=(const Runtime&) = delete;

 private:
  explicit Runtime(const DeviceInfo& device);
  cl_program build_program(const std::string& program, const std::string& options);
  cl_program built_program(const std::string& program, const std::string& options);  // cached build

  DeviceInfo device_;
  cl_context context_ = nullptr;
  cl_command_queue queue_ = nullptr;
  std::map<std::string, cl_program> programs_;  // key: program + '\n' + options
  std::map<std::string, cl_kernel> kernels_;    // key: program + '\n' + options + '\n' + name
  struct PooledBuffer {
    cl_mem mem;
    uint64_t released_at;  // allocate() calls made before it was pooled
  };
  void release_idle_buffers();
  void release_superseded_buffers(size_t cls);
  static constexpr uint64_t kPoolSweepEvery = 256;          // allocate() calls between sweeps
  static constexpr size_t kPoolSupersedeFrom = size_t(1) << 20;  // see release_superseded_buffers
  std::map<size_t, std::vector<PooledBuffer>> pool_;  // key: rounded size in bytes
  uint64_t allocations_ = 0;
  size_t pooled_bytes_ = 0, pool_cap_bytes_ = 0;
  size_t live_bytes_ = 0, peak_live_bytes_ = 0;
  bool profiling_ = false;
  std::vector<std::pair<std::string, cl_event>> pending_events_;
  std::map<std::string, KernelTiming> totals_;
};

// Where stylerf keeps caches: $STYLERF_CACHE_DIR, else $XDG_CACHE_HOME/stylerf, else ~/.cache/stylerf.
std::string cache_dir();

// Makes sure POCL_CACHE_DIR points at our cache (unless the user set it). Safe to call repeatedly;
// must run before the first OpenCL call of the process to take effect, which Runtime does.
void configure_driver_caches();

}  // namespace stylerf::host
