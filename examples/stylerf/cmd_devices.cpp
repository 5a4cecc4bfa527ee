// stylerf devices: list OpenCL devices and show which one would be chosen.
#include <iostream>

#include "examples/stylerf/commands.hpp"
#include "host/device.hpp"

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
  return 0;
}
stylerf::cli::Register reg("devices", "list OpenCL devices and the one stylerf would use", run_devices);
}  // namespace
