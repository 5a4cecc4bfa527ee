// stylerf devices: list OpenCL devices and show which one would be chosen.
#include <iostream>

#include "examples/stylerf/commands.hpp"
#include "host/device.hpp"
#include "lib/field/vm_grid.hpp"
#include "lib/nn/ops.hpp"
#include "lib/nn/reduce_path.hpp"

namespace {
int run_devices(int argc, char** argv) {
  using namespace stylerf::host;
  for (const auto& d : list_devices()) std::cout << d.describe() << "\n";
  // `stylerf devices [SPEC]` or `stylerf devices --device SPEC`.
  std::string spec = argc > 1 ? argv[1] : "";
  if (spec == "--device") spec = argc > 2 ? argv[2] : "";
  DeviceInfo chosen = choose_device(spec);
  std::cout << "chosen: [" << chosen.index << "] " << chosen.name
            << "   (pick with --device INDEX|cpu|gpu|NAME or STYLERF_DEVICE)\n";
  // The paths the kernels take there by default, and the extensions they depend on.
  auto yes = [&](const char* ext) { return chosen.has_extension(ext) ? "yes" : "no"; };
  std::cout << "  grid scatter: " << stylerf::field::scatter_mode_name(stylerf::field::auto_scatter_mode(chosen))
            << ", reductions: "
            << (stylerf::nn::detail::group_reductions_by_default(chosen) ? "work-group" : "per-item")
            << "; 64-bit atomics: " << yes("cl_khr_int64_base_atomics")
            << ", float atomics: " << yes("cl_ext_float_atomics") << ", fp64: " << yes("cl_khr_fp64") << "\n";
  // Whether the device's kernels flush denormal floats (the library builds them with -cl-denorms-are-zero).
  stylerf::cli::init_runtime(std::to_string(chosen.index), false);
  std::cout << "  denormals: "
            << (stylerf::nn::device_flushes_denormals() ? "flushed to zero" : "kept (x86 CPUs run them slowly)") << "\n";
  return 0;
}
stylerf::cli::Register reg("devices", "list OpenCL devices and the one stylerf would use", run_devices);
}  // namespace
