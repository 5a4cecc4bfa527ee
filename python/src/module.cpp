// The extension module stylerf._stylerf: the library's errors as stylerf.Error (a RuntimeError, the
// library's message unchanged), the OpenCL device, and the bindings of the other files.
#include "host/device.hpp"
#include "host/error.hpp"
#include "host/runtime.hpp"
#include "lib/nn/ops.hpp"
#include "lib/version.hpp"
#include "python/src/handles.hpp"

namespace stylerf::py {

namespace {

pyb::dict device_dict(const host::DeviceInfo& d) {
  pyb::dict out;
  out["index"] = d.index;
  out["name"] = d.name;
  out["vendor"] = d.vendor;
  out["type"] = d.type_name();
  out["platform"] = d.platform_name;
  out["global_mem_bytes"] = d.global_mem_bytes;
  out["compute_units"] = d.compute_units;
  return out;
}

}  // namespace

void bind_runtime(pyb::module_& m) {
  m.def("devices", [] {
    pyb::list out;
    for (const auto& d : host::list_devices()) out.append(device_dict(d));
    return out;
  }, "The OpenCL devices, in the order an index picks them.");
  m.def("use_device", [](const std::string& spec) {
    LibraryCall call;
    host::Runtime::init(spec);
  }, pyb::arg("spec"),
        "Chooses the device before the first computation: spec is an index, cpu, gpu, accelerator, or part of a "
        "name (default: $STYLERF_DEVICE, else the first GPU, else the first device); once chosen it stays.");
  m.def("device", [] {
    host::DeviceInfo d;
    bool flushes = false;
    {
      LibraryCall call;
      d = host::Runtime::instance().device();
      flushes = nn::device_flushes_denormals();
    }
    pyb::dict out = device_dict(d);
    out["denormals_flushed"] = flushes;
    return out;
  }, "The device in use (choosing the default one if none was chosen yet); denormals_flushed: whether its "
     "kernels flush floats below 1e-38 to zero (the library sets that up on CPU devices: x86 runs them slowly).");
  m.def("_shutdown", [] {
    LibraryCall call;
    if (host::Runtime::initialised()) host::Runtime::shutdown();
  }, "drain the queue and release the device (registered with atexit by stylerf/__init__.py)");
}

}  // namespace stylerf::py

PYBIND11_MODULE(_stylerf, m) {
  namespace py = stylerf::py;
  m.doc() = "stylerf: zero-shot 3D style transfer of radiance fields (OpenCL)";
  m.attr("__version__") = stylerf::version();
  m.attr("__commit__") = stylerf::git_commit();  // the git commit built from, or "unknown"
  static pybind11::exception<stylerf::host::Error> error(m, "Error", PyExc_RuntimeError);
  error.attr("__doc__") =
      "An error of the library (a missing file, a bad checkpoint, a device failure), its message unchanged.";
  pybind11::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const stylerf::host::Error& e) {
      error(e.what());
    }
  });
  py::bind_runtime(m);
  py::bind_scene(m);
  py::bind_model(m);
  py::bind_train(m);
  py::bind_eval(m);
  py::bind_image(m);
}
