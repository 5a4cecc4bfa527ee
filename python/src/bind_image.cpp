// Image files as numpy arrays, read and written as the library reads and writes them: a user compares our
// PNGs with their own arrays, and writes frames and videos, without another imaging package.
#include <pybind11/numpy.h>

#include <cmath>

#include "lib/io/image.hpp"
#include "lib/io/video.hpp"
#include "python/src/arrays.hpp"
#include "python/src/handles.hpp"
#include "python/src/path_args.hpp"

namespace stylerf::py {

namespace {

namespace fs = std::filesystem;

pyb::array_t<float> load_image(const fs::path& path_arg_) {
  const std::string path = path_arg(path_arg_, "path");
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

void save_image(const fs::path& path_arg_, const pyb::object& image) {
  const std::string path = path_arg(path_arg_, "path");
  const io::Image img = image_from_array(image, "image");
  LibraryCall call;
  io::save_image(path, img);
}

// Every frame's height and width must be the first one's: checked on the shapes alone before any frame is
// converted or written, so a long video fails at once rather than at its odd frame.
void check_frame_sizes(const pyb::sequence& frames) {
  pyb::ssize_t h0 = -1, w0 = -1;
  for (size_t i = 0; i < frames.size(); ++i) {
    const pyb::object f = frames[i];
    if (!pyb::isinstance<pyb::array>(f)) continue;  // image_from_array names what it is instead
    const auto a = pyb::reinterpret_borrow<pyb::array>(f);
    if (a.ndim() < 2) continue;
    if (i == 0) {
      h0 = a.shape(0), w0 = a.shape(1);
    } else if (h0 >= 0 && (a.shape(0) != h0 || a.shape(1) != w0)) {
      throw pyb::value_error("frames[" + std::to_string(i) + "]: " + std::to_string(a.shape(0)) + " x " +
                             std::to_string(a.shape(1)) + " pixels, frames[0] " + std::to_string(h0) + " x " +
                             std::to_string(w0) + "; every frame must have the same size");
    }
  }
}

void save_video(const pyb::sequence& frames, const fs::path& path_arg_, double fps) {
  const std::string path = path_arg(path_arg_, "path");
  if (frames.size() == 0) throw pyb::value_error("frames: empty; give at least one H x W x 3 image");
  if (!(fps > 0 && fps <= 1000))
    throw pyb::value_error("fps: must be a positive number of frames a second, at most 1000 (got " +
                           std::string(pyb::str(pyb::float_(fps))) + ")");
  check_frame_sizes(frames);
  LibraryCall call;
  io::save_video(path, int(frames.size()), [&](int i) {
    pyb::gil_scoped_acquire gil;  // the frames are Python objects: read each with the GIL held
    return image_from_array(frames[size_t(i)], "frames[" + std::to_string(i) + "]");
  }, fps);
}

}  // namespace

void bind_image(pyb::module_& m) {
  m.def("load_image", &load_image, pyb::arg("path"),
        "An image file (PNG, JPEG, ...) as H x W x 3 float32 in [0, 1] (alpha dropped, grey replicated).");
  m.def("save_image", &save_image, pyb::arg("path"), pyb::arg("image"),
        "Writes an H x W x 3 image (float32 in [0, 1] or uint8) to a PNG or JPEG file, by its name's extension, "
        "8 bits per channel, rounded.");
  m.def("save_video", &save_video, pyb::arg("frames"), pyb::arg("path"), pyb::arg("fps") = 30.0,
        "Writes frames (a sequence of H x W x 3 images of one size, float32 in [0, 1] or uint8) to an mp4 video at "
        "fps frames a second, as the CLI writes its videos: H.264 through ffmpeg, which must be on PATH.");
}

}  // namespace stylerf::py
