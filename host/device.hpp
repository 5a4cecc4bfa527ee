// Discovery and choice of OpenCL devices.
#pragma once
#include <CL/cl.h>

#include <cstddef>
#include <string>
#include <vector>

namespace stylerf::host {

struct DeviceInfo {
  int index = 0;  // position in list_devices()
  cl_platform_id platform = nullptr;
  cl_device_id id = nullptr;
  std::string name, vendor, version, driver, platform_name;
  std::string extensions;  // CL_DEVICE_EXTENSIONS, space separated
  cl_device_type type = 0;
  size_t global_mem_bytes = 0, max_alloc_bytes = 0, max_work_group = 0;
  cl_uint compute_units = 0;

  std::string type_name() const;  // "cpu", "gpu", "accelerator", "other"
  bool is_pocl() const;
  bool has_extension(const std::string& ext) const;  // a whole word of `extensions`
  std::string describe() const;   // one line for `stylerf devices`
};

// Every device of every platform, in a stable order. Throws when no platform is installed.
std::vector<DeviceInfo> list_devices();

// Picks a device by spec: "" (then $STYLERF_DEVICE, then the first GPU, else the first device),
// an index ("1"), a type ("cpu", "gpu", "accelerator"), or a case-insensitive name substring.
// An unknown spec throws an Error that lists the devices there are.
DeviceInfo choose_device(const std::string& spec);

}  // namespace stylerf::host
