// Image files as numpy arrays, read and written as the library reads and writes them: a user compares our
// PNGs with their own arrays, and writes frames for a video, without another imaging package.
#include <pybind11/numpy.h>

#include "lib/io/image.hpp"
#include "python/src/arrays.hpp"
#include "python/src/handles.hpp"

namespace stylerf::py {

namespace {

pyb::array_t<float> load_image(const std::string& path) {
  io::Image img;
  {
    LibraryCall call;
    img = io::load_image(path);  // alpha dropped, grey replicated: RGB in [0, 1]
  }
  const size_t plane = size_t(img.width) * img.height;
  std::vector<float> hwc(3 * plane);
  for (size_t i = 0; i < plane; ++i)
    for (int c = 0; c < 3; ++c) hwc[3 * i + c] = img.data[c * plane + i];
  return to_array(std::move(hwc), img.height, img.width, 3);
}

void save_image(const std::string& path, const pyb::object& image) {
  const io::Image img = image_from_array(image, "image");
  LibraryCall call;
  io::save_image(path, img);
}

}  // namespace

void bind_image(pyb::module_& m) {
  m.def("load_image", &load_image, pyb::arg("path"), "an image file (PNG, JPEG, ...) as H x W x 3 float32 in [0, 1]");
  m.def("save_image", &save_image, pyb::arg("path"), pyb::arg("image"),
        "an H x W x 3 image to a PNG or JPEG file (by its name), 8 bits per channel, rounded");
}

}  // namespace stylerf::py
