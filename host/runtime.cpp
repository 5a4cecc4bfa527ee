#include "host/runtime.hpp"

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <sstream>

#include "host/embedded.hpp"
#include "host/error.hpp"
#include "host/files.hpp"

namespace stylerf::host {
namespace {

// The process-wide runtime. Not a function-local static: its destructor must run before the driver's
// own static destructors (PoCL's LLVM), and a static registered before the driver is loaded would run
// after them. So it is destroyed by an atexit handler registered once the driver is loaded, which runs
// first (handlers run in reverse order of registration).
Runtime* g_runtime = nullptr;

void destroy_runtime() {
  delete g_runtime;
  g_runtime = nullptr;
}

uint64_t fnv1a(const std::string& s, uint64_t h = 1469598103934665603ull) {
  for (unsigned char c : s) {
    h ^= c;
    h *= 1099511628211ull;
  }
  return h;
}

std::string hex64(uint64_t v) {
  std::ostringstream o;
  o << std::hex << std::setw(16) << std::setfill('0') << v;
  return o.str();
}

}  // namespace

std::string cache_dir() {
  if (const char* d = std::getenv("STYLERF_CACHE_DIR"); d && *d) return d;
  if (const char* x = std::getenv("XDG_CACHE_HOME"); x && *x) return std::string(x) + "/stylerf";
  if (const char* h = std::getenv("HOME"); h && *h) return std::string(h) + "/.cache/stylerf";
  return "/tmp/stylerf-cache";
}

void configure_driver_caches() {
  const char* pocl = std::getenv("POCL_CACHE_DIR");
  if (pocl && *pocl) return;
  std::string dir = cache_dir() + "/pocl";
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (!ec) setenv("POCL_CACHE_DIR", dir.c_str(), 0);
}

Runtime& Runtime::init(const std::string& device_spec) {
  if (g_runtime) {
    if (!device_spec.empty()) {
      DeviceInfo want = choose_device(device_spec);
      if (want.id != g_runtime->device_.id)
        throw Error("the OpenCL runtime is already running on '" + g_runtime->device_.name +
                    "'; it cannot switch to '" + want.name + "' within one process");
    }
    return *g_runtime;
  }
  configure_driver_caches();
  DeviceInfo device = choose_device(device_spec);  // loads the OpenCL driver
  g_runtime = new Runtime(device);
  std::atexit(destroy_runtime);
  return *g_runtime;
}

Runtime& Runtime::instance() { return g_runtime ? *g_runtime : init(""); }

bool Runtime::initialised() { return g_runtime != nullptr; }

void Runtime::shutdown() {
  if (!g_runtime) return;
  g_runtime->finish();
  destroy_runtime();
}

Runtime::Runtime(const DeviceInfo& device) : device_(device) {
  cl_int err = CL_SUCCESS;
  cl_context_properties props[] = {CL_CONTEXT_PLATFORM, reinterpret_cast<cl_context_properties>(device_.platform),
                                   0};
  context_ = clCreateContext(props, 1, &device_.id, nullptr, nullptr, &err);
  check(err, "clCreateContext", device_.name);
  // OpenCL 1.2 API: in-order queue with profiling (deprecated in 2.0 but universally available).
#if defined(__GNUC__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wdeprecated-declarations"
#endif
  queue_ = clCreateCommandQueue(context_, device_.id, CL_QUEUE_PROFILING_ENABLE, &err);
#if defined(__GNUC__)
#pragma GCC diagnostic pop
#endif
  check(err, "clCreateCommandQueue", device_.name);
  if (const char* p = std::getenv("STYLERF_PROFILE"); p && std::string(p) == "1") profiling_ = true;
  pool_cap_bytes_ = default_pool_cap_bytes((device_.type & CL_DEVICE_TYPE_CPU) != 0, device_.global_mem_bytes);
  if (const char* c = std::getenv("STYLERF_POOL_MIB"); c && *c) {
    char* end = nullptr;
    const unsigned long long mib = std::strtoull(c, &end, 10);
    if (end == c || *end != '\0')
      throw Error(std::string("STYLERF_POOL_MIB='") + c + "' is not a whole number of MiB (the buffer pool's cap)");
    pool_cap_bytes_ = size_t(mib) << 20;
  }
}

size_t default_pool_cap_bytes(bool cpu_device, size_t global_mem_bytes) {
  constexpr size_t kGiB = size_t(1) << 30;
  if (cpu_device) return std::max(global_mem_bytes / 4, std::min(global_mem_bytes / 2, 4 * kGiB));
  return std::min(global_mem_bytes / 4, kGiB);
}

Runtime::~Runtime() {
  // Let queued work (and any kernel compile it triggers) finish before anything is released.
  if (queue_) clFinish(queue_);
  trim_buffer_pool();
  for (auto& e : pending_events_) clReleaseEvent(e.second);
  for (auto& k : kernels_) clReleaseKernel(k.second);
  for (auto& p : programs_) clReleaseProgram(p.second);
  if (queue_) clReleaseCommandQueue(queue_);
  if (context_) clReleaseContext(context_);
}

std::string Runtime::program_source(const std::string& program) const {
  // "a+b+c": the files concatenated in that order, one program (kernels that use the helpers of others).
  if (const size_t plus = program.find('+'); plus != std::string::npos)
    return program_source(program.substr(0, plus)) + "\n" + program_source(program.substr(plus + 1));
  if (const char* dir = std::getenv("STYLERF_KERNEL_DIR"); dir && *dir) {
    std::string path = std::string(dir) + "/" + program + ".cl";
    std::ifstream in(path, std::ios::binary);
    if (!in) throw Error("STYLERF_KERNEL_DIR is set but " + path + " cannot be read");
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
  }
  for (const auto& f : embedded_kernels())
    if (program == f.name) return f.text;
  throw Error("no OpenCL program named '" + program + "' (kernels/" + program + ".cl) was built into stylerf");
}

cl_program Runtime::build_program(const std::string& program, const std::string& options) {
  // kernels/common.cl (shared helpers, include-guarded) goes in front of every program.
  const std::string source = (program == "common" ? "" : program_source("common") + "\n") + program_source(program);
  // STYLERF_CL_OPTIONS adds build options for every program, e.g. "-Drestrict=" for Oclgrind, whose
  // LLVM cannot build kernels with restrict pointers (scripts/oclgrind.sh).
  const char* extra = std::getenv("STYLERF_CL_OPTIONS");
  // -cl-denorms-are-zero: x86 CPUs take a slow path (microcode assists) for every float below 1e-38 unless
  // the thread flushes them, and training on mostly empty space produces such values (one model's steps ran
  // 1.7x slower with them kept; docs/results.md). Nothing we compute means anything below 1e-38. PoCL sets
  // the flush mode on whichever thread runs one of these kernels, for that kernel only, so a caller's own
  // arithmetic keeps its mode (the host-BLAS engine flushes on its own threads: host/fp_mode.hpp). A GPU's
  // compiler may flush too; the option allows it and requires nothing.
  const std::string full_options = "-cl-std=CL1.2 -cl-mad-enable -cl-denorms-are-zero " + options +
                                   (extra && *extra ? std::string(" ") + extra : std::string());
  cl_int err = CL_SUCCESS;
  cl_program prog = nullptr;

  // Drivers other than PoCL get a binary cache of ours; PoCL caches by itself in POCL_CACHE_DIR.
  std::string cache_path;
  if (!device_.is_pocl()) {
    uint64_t h = fnv1a(source);
    h = fnv1a(full_options, h);
    h = fnv1a(device_.name + '\n' + device_.driver + '\n' + device_.platform_name, h);
    cache_path = cache_dir() + "/programs/" + program + "-" + hex64(h) + ".bin";
    std::ifstream in(cache_path, std::ios::binary);
    if (in) {
      std::string bin((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
      const unsigned char* ptr = reinterpret_cast<const unsigned char*>(bin.data());
      size_t len = bin.size();
      cl_int status = CL_SUCCESS;
      prog = clCreateProgramWithBinary(context_, 1, &device_.id, &len, &ptr, &status, &err);
      if (err != CL_SUCCESS || status != CL_SUCCESS) prog = nullptr;
      if (prog && clBuildProgram(prog, 1, &device_.id, full_options.c_str(), nullptr, nullptr) != CL_SUCCESS) {
        clReleaseProgram(prog);
        prog = nullptr;
      }
      if (prog) return prog;
    }
  }

  const char* src = source.c_str();
  size_t len = source.size();
  prog = clCreateProgramWithSource(context_, 1, &src, &len, &err);
  check(err, "clCreateProgramWithSource", "kernels/" + program + ".cl");
  err = clBuildProgram(prog, 1, &device_.id, full_options.c_str(), nullptr, nullptr);
  if (err != CL_SUCCESS) {
    size_t n = 0;
    clGetProgramBuildInfo(prog, device_.id, CL_PROGRAM_BUILD_LOG, 0, nullptr, &n);
    std::string log(n, '\0');
    clGetProgramBuildInfo(prog, device_.id, CL_PROGRAM_BUILD_LOG, n, log.data(), nullptr);
    clReleaseProgram(prog);
    throw Error("clBuildProgram failed for kernels/" + program + ".cl with options '" + options +
                "': " + cl_error_name(err) + "\n" + log);
  }
  if (!cache_path.empty()) {
    size_t bin_size = 0;
    if (clGetProgramInfo(prog, CL_PROGRAM_BINARY_SIZES, sizeof(bin_size), &bin_size, nullptr) == CL_SUCCESS &&
        bin_size > 0) {
      std::string bin(bin_size, '\0');
      unsigned char* ptr = reinterpret_cast<unsigned char*>(bin.data());
      if (clGetProgramInfo(prog, CL_PROGRAM_BINARIES, sizeof(ptr), &ptr, nullptr) == CL_SUCCESS) {
        try {
          write_file_atomic(cache_path, bin);
        } catch (const std::exception&) {
          // A cache we cannot write only costs compile time next run.
        }
      }
    }
  }
  return prog;
}

cl_program Runtime::built_program(const std::string& program, const std::string& options) {
  const std::string key = program + '\n' + options;
  auto it = programs_.find(key);
  if (it == programs_.end()) it = programs_.emplace(key, build_program(program, options)).first;
  return it->second;
}

void Runtime::build(const ProgramBuild& p) { built_program(p.program, p.options); }

cl_kernel Runtime::kernel(const std::string& program, const std::string& name, const std::string& options) {
  const std::string kkey = program + '\n' + options + '\n' + name;
  if (auto it = kernels_.find(kkey); it != kernels_.end()) return it->second;
  cl_int err = CL_SUCCESS;
  cl_kernel k = clCreateKernel(built_program(program, options), name.c_str(), &err);
  check(err, "clCreateKernel", "kernel '" + name + "' in kernels/" + program + ".cl");
  kernels_.emplace(kkey, k);
  return k;
}

namespace {
// Pool size classes: exact below 64 KiB (many small tensors), else rounded up to 1/16 of the power of two,
// so slightly different shapes share buffers while wasting at most ~6%.
size_t pool_size_class(size_t bytes) {
  bytes = std::max<size_t>(bytes, 4);
  if (bytes <= 65536) return (bytes + 255) / 256 * 256;
  size_t p = 1;
  while (p < bytes) p <<= 1;
  size_t step = p / 16;
  return (bytes + step - 1) / step * step;
}
}  // namespace

cl_mem Runtime::allocate(size_t bytes, const std::string& what) {
  auto limits = [&] {
    std::ostringstream o;
    o << "allocating " << bytes << " bytes (" << std::fixed << std::setprecision(1) << bytes / 1048576.0
      << " MiB) for " << what << " on '" << device_.name << "' failed: the device allows at most "
      << (device_.max_alloc_bytes >> 20) << " MiB per buffer and has " << (device_.global_mem_bytes >> 20)
      << " MiB in all";
    return o.str();
  };
  if (bytes > device_.max_alloc_bytes) throw Error(limits() + " (request exceeds the per-buffer limit)");
  auto count = [&](cl_mem m) {
    live_bytes_ += bytes;
    peak_live_bytes_ = std::max(peak_live_bytes_, live_bytes_);
    return m;
  };
  const size_t cls = std::min(pool_size_class(bytes), device_.max_alloc_bytes);
  if (++allocations_ % kPoolSweepEvery == 0) release_idle_buffers();
  // The smallest pooled buffer of this class or up to twice its size. Per-sample tensors change size from
  // step to step (the samples a batch keeps: 0.8 to 1.5 million at once on an object capture); with a
  // quarter's tolerance each new size range got its own buffers, and the feature stage pooled 4.8 GB to
  // serve a 1.4 GB step.
  for (auto it = pool_.lower_bound(cls); it != pool_.end() && it->first <= 2 * cls; ++it) {
    if (it->second.empty()) continue;
    cl_mem m = it->second.back().mem;
    it->second.pop_back();
    pooled_bytes_ -= it->first;
    return count(m);
  }
  release_superseded_buffers(cls);
  cl_int err = CL_SUCCESS;
  cl_mem m = clCreateBuffer(context_, CL_MEM_READ_WRITE, cls, nullptr, &err);
  if (err != CL_SUCCESS && !pool_.empty()) {  // memory held by the pool may be what is missing
    trim_buffer_pool();
    m = clCreateBuffer(context_, CL_MEM_READ_WRITE, cls, nullptr, &err);
  }
  if (err != CL_SUCCESS) throw Error(limits() + ": clCreateBuffer returned " + cl_error_name(err));
  return count(m);
}

void Runtime::release(cl_mem mem, size_t bytes) {
  if (!mem) return;
  live_bytes_ -= std::min(live_bytes_, bytes);
  // Keyed by the buffer's own size: allocate() may have handed out a larger one than `bytes` asks for.
  size_t cls = std::min(pool_size_class(bytes), device_.max_alloc_bytes);
  size_t actual = 0;
  if (clGetMemObjectInfo(mem, CL_MEM_SIZE, sizeof actual, &actual, nullptr) == CL_SUCCESS && actual >= cls) cls = actual;
  // A buffer over a quarter of the cap is a one-off (the stage-2 target maps, 2 GB at 800x800), not a step's
  // temporary: pooling it would hold its memory for the rest of the run.
  if (pooled_bytes_ + cls > pool_cap_bytes_ || cls > pool_cap_bytes_ / 4) {
    clReleaseMemObject(mem);
    return;
  }
  pool_[cls].push_back({mem, allocations_});
  pooled_bytes_ += cls;
}

void Runtime::release_superseded_buffers(size_t cls) {
  // The fresh buffer of class `cls` will serve the requests that pooled buffers of half its size up to its
  // own would: a step whose kept samples grew past them keeps just the largest. Small classes are left
  // alone (they cost little, and many different small tensors live at once).
  if (cls < kPoolSupersedeFrom) return;
  for (auto it = pool_.lower_bound(cls / 2); it != pool_.end() && it->first < cls;) {
    for (const PooledBuffer& b : it->second) clReleaseMemObject(b.mem);
    pooled_bytes_ -= it->second.size() * it->first;
    it = pool_.erase(it);
  }
}

void Runtime::release_idle_buffers() {
  // Idle for kPoolIdleAllocations allocate() calls: a size the loop no longer asks for (or a one-off
  // phase's). A training step makes ~100 (feature stage) to ~500 (style stage's rendered step) of them.
  for (auto it = pool_.begin(); it != pool_.end();) {
    auto& buffers = it->second;  // filed in release order: the longest idle first
    size_t idle = 0;
    while (idle < buffers.size() && allocations_ - buffers[idle].released_at > kPoolIdleAllocations) ++idle;
    for (size_t i = 0; i < idle; ++i) clReleaseMemObject(buffers[i].mem);
    buffers.erase(buffers.begin(), buffers.begin() + long(idle));
    pooled_bytes_ -= idle * it->first;
    it = buffers.empty() ? pool_.erase(it) : std::next(it);
  }
}

void Runtime::trim_buffer_pool() {
  for (auto& kv : pool_)
    for (const PooledBuffer& b : kv.second) clReleaseMemObject(b.mem);
  pool_.clear();
  pooled_bytes_ = 0;
}

void Runtime::finish() { check(clFinish(queue_), "clFinish"); }

void Runtime::record(const std::string& kernel_name, cl_event event) {
  pending_events_.emplace_back(kernel_name, event);
  if (pending_events_.size() > 4096) timings();  // bound the number of live events
}

void Runtime::record_host(const std::string& name, double ms) {
  auto& t = totals_[name];
  t.kernel = name;
  t.launches += 1;
  t.total_ms += ms;
}

std::vector<KernelTiming> Runtime::timings() {
  if (!pending_events_.empty()) {
    finish();
    for (auto& [name, ev] : pending_events_) {
      cl_ulong t0 = 0, t1 = 0;
      check(clGetEventProfilingInfo(ev, CL_PROFILING_COMMAND_START, sizeof(t0), &t0, nullptr),
            "clGetEventProfilingInfo", name);
      check(clGetEventProfilingInfo(ev, CL_PROFILING_COMMAND_END, sizeof(t1), &t1, nullptr),
            "clGetEventProfilingInfo", name);
      auto& t = totals_[name];
      t.kernel = name;
      t.launches += 1;
      t.total_ms += (t1 - t0) * 1e-6;
      clReleaseEvent(ev);
    }
    pending_events_.clear();
  }
  std::vector<KernelTiming> out;
  for (auto& kv : totals_) out.push_back(kv.second);
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.total_ms > b.total_ms; });
  return out;
}

void Runtime::reset_timings() {
  timings();
  totals_.clear();
}

std::string Runtime::timing_report() {
  std::ostringstream o;
  o << std::left << std::setw(36) << "kernel" << std::right << std::setw(10) << "launches" << std::setw(14)
    << "total ms" << std::setw(12) << "ms/launch" << "\n";
  for (const auto& t : timings())
    o << std::left << std::setw(36) << t.kernel << std::right << std::setw(10) << t.launches << std::setw(14)
      << std::fixed << std::setprecision(3) << t.total_ms << std::setw(12) << t.total_ms / t.launches << "\n";
  return o.str();
}

}  // namespace stylerf::host
