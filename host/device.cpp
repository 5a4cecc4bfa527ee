#include "host/device.hpp"

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <sstream>

#include "host/error.hpp"

namespace stylerf::host {
namespace {

std::string device_string(cl_device_id d, cl_device_info what) {
  size_t n = 0;
  check(clGetDeviceInfo(d, what, 0, nullptr, &n), "clGetDeviceInfo");
  std::string s(n, '\0');
  check(clGetDeviceInfo(d, what, n, s.data(), nullptr), "clGetDeviceInfo");
  while (!s.empty() && (s.back() == '\0' || s.back() == ' ')) s.pop_back();
  return s;
}

template <class T>
T device_value(cl_device_id d, cl_device_info what) {
  T v{};
  check(clGetDeviceInfo(d, what, sizeof(T), &v, nullptr), "clGetDeviceInfo");
  return v;
}

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

}  // namespace

std::string DeviceInfo::type_name() const {
  if (type & CL_DEVICE_TYPE_GPU) return "gpu";
  if (type & CL_DEVICE_TYPE_CPU) return "cpu";
  if (type & CL_DEVICE_TYPE_ACCELERATOR) return "accelerator";
  return "other";
}

bool DeviceInfo::is_pocl() const {
  return platform_name.find("Portable Computing Language") != std::string::npos;
}

bool DeviceInfo::has_extension(const std::string& ext) const {
  size_t at = 0;
  while ((at = extensions.find(ext, at)) != std::string::npos) {
    const size_t end = at + ext.size();
    if ((at == 0 || extensions[at - 1] == ' ') && (end == extensions.size() || extensions[end] == ' ')) return true;
    at = end;
  }
  return false;
}

std::string DeviceInfo::describe() const {
  std::ostringstream o;
  o << "[" << index << "] " << type_name() << "  " << name << "  (" << platform_name << ", driver "
    << driver << ")  " << compute_units << " CUs, " << (global_mem_bytes >> 20) << " MiB, max alloc "
    << (max_alloc_bytes >> 20) << " MiB";
  return o.str();
}

std::vector<DeviceInfo> list_devices() {
  cl_uint np = 0;
  cl_int err = clGetPlatformIDs(0, nullptr, &np);
  if (err == -1001 /* CL_PLATFORM_NOT_FOUND_KHR */ || np == 0)
    throw Error("no OpenCL platform found: install an ICD (e.g. `apt-get install pocl-opencl-icd`)");
  check(err, "clGetPlatformIDs");
  std::vector<cl_platform_id> platforms(np);
  check(clGetPlatformIDs(np, platforms.data(), nullptr), "clGetPlatformIDs");
  std::vector<DeviceInfo> out;
  for (cl_platform_id p : platforms) {
    size_t n = 0;
    check(clGetPlatformInfo(p, CL_PLATFORM_NAME, 0, nullptr, &n), "clGetPlatformInfo");
    std::string pname(n, '\0');
    check(clGetPlatformInfo(p, CL_PLATFORM_NAME, n, pname.data(), nullptr), "clGetPlatformInfo");
    while (!pname.empty() && pname.back() == '\0') pname.pop_back();
    cl_uint nd = 0;
    err = clGetDeviceIDs(p, CL_DEVICE_TYPE_ALL, 0, nullptr, &nd);
    if (err == CL_DEVICE_NOT_FOUND || nd == 0) continue;
    check(err, "clGetDeviceIDs", pname);
    std::vector<cl_device_id> ids(nd);
    check(clGetDeviceIDs(p, CL_DEVICE_TYPE_ALL, nd, ids.data(), nullptr), "clGetDeviceIDs", pname);
    for (cl_device_id d : ids) {
      DeviceInfo info;
      info.index = static_cast<int>(out.size());
      info.platform = p;
      info.id = d;
      info.platform_name = pname;
      info.name = device_string(d, CL_DEVICE_NAME);
      info.vendor = device_string(d, CL_DEVICE_VENDOR);
      info.version = device_string(d, CL_DEVICE_VERSION);
      info.driver = device_string(d, CL_DRIVER_VERSION);
      info.extensions = device_string(d, CL_DEVICE_EXTENSIONS);
      info.type = device_value<cl_device_type>(d, CL_DEVICE_TYPE);
      info.global_mem_bytes = device_value<cl_ulong>(d, CL_DEVICE_GLOBAL_MEM_SIZE);
      info.max_alloc_bytes = device_value<cl_ulong>(d, CL_DEVICE_MAX_MEM_ALLOC_SIZE);
      info.max_work_group = device_value<size_t>(d, CL_DEVICE_MAX_WORK_GROUP_SIZE);
      info.compute_units = device_value<cl_uint>(d, CL_DEVICE_MAX_COMPUTE_UNITS);
      out.push_back(std::move(info));
    }
  }
  if (out.empty()) throw Error("no OpenCL device found on any platform");
  return out;
}

DeviceInfo choose_device(const std::string& spec_in) {
  std::vector<DeviceInfo> devices = list_devices();
  std::string spec = spec_in;
  if (spec.empty()) {
    if (const char* env = std::getenv("STYLERF_DEVICE")) spec = env;
  }
  if (spec.empty()) {
    for (const auto& d : devices)
      if (d.type & CL_DEVICE_TYPE_GPU) return d;
    return devices.front();
  }
  std::string s = lower(spec);
  bool numeric = !s.empty() && std::all_of(s.begin(), s.end(), [](unsigned char c) { return std::isdigit(c); });
  if (numeric) {
    size_t i = std::stoul(s);
    if (i < devices.size()) return devices[i];
  } else {
    for (const auto& d : devices)
      if (d.type_name() == s) return d;
    for (const auto& d : devices)
      if (lower(d.name).find(s) != std::string::npos || lower(d.platform_name).find(s) != std::string::npos)
        return d;
  }
  std::ostringstream msg;
  const char* from = spec_in.empty() ? "STYLERF_DEVICE" : "--device";
  if (s == "gpu" || s == "cpu" || s == "accelerator") {
    msg << "no OpenCL " << (s == "gpu" ? "GPU" : s == "cpu" ? "CPU" : "accelerator") << " device was found (asked for by "
        << from << "=" << spec << "); unset it or pick one of the devices found:";
    for (const auto& d : devices) msg << "\n  " << d.describe();
    throw Error(msg.str());
  }
  if (numeric) {
    msg << "no OpenCL device " << spec << " (asked for by " << from << "): " << devices.size() << " found:";
    for (const auto& d : devices) msg << "\n  " << d.describe();
    throw Error(msg.str());
  }
  msg << "unknown OpenCL device '" << spec << "' (from " << from << "; give an index, a type cpu|gpu|accelerator, or part of a name). "
      << "Devices found:";
  for (const auto& d : devices) msg << "\n  " << d.describe();
  throw Error(msg.str());
}

}  // namespace stylerf::host
