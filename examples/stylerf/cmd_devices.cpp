// stylerf devices: list OpenCL devices and show which one would be chosen.
#include <boost/program_options.hpp>
#include <iostream>

#include "examples/stylerf/commands.hpp"
#include "examples/stylerf/help.hpp"
#include "host/device.hpp"
#include "lib/field/vm_grid.hpp"
#include "lib/nn/ops.hpp"
#include "lib/nn/reduce_path.hpp"

namespace po = boost::program_options;

namespace {
// `stylerf devices [SPEC]` or `stylerf devices --device SPEC`. Returns -1 to go on, else the exit code.
int parse_devices_args(int argc, char** argv, std::string& spec) {
  po::options_description desc("stylerf devices [SPEC | --device SPEC] [options]");
  desc.add_options()("help,h", "show this help")(
      "device", po::value(&spec), stylerf::cli::kDeviceHelp);
  po::positional_options_description pos;
  pos.add("device", 1);
  po::variables_map vm;
  po::store(po::command_line_parser(argc, argv).options(desc).positional(pos).run(), vm);
  po::notify(vm);
  if (!vm.count("help")) return -1;
  stylerf::cli::print_help(std::cout, "devices", desc,
                           "Prints this machine's OpenCL devices, the one SPEC chooses, the kernel paths taken there\n"
                           "and the extensions they depend on.");
  return 0;
}

int run_devices(int argc, char** argv) {
  using namespace stylerf::host;
  std::string spec;
  if (const int rc = parse_devices_args(argc, argv, spec); rc >= 0) return rc;
  for (const auto& d : list_devices()) std::cout << d.describe() << "\n";
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
stylerf::cli::Register reg("devices", run_devices);
}  // namespace
