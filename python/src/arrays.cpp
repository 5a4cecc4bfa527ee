#include "python/src/arrays.hpp"

#include <cmath>
#include <memory>

namespace stylerf::py {

namespace {

std::string shape_text(const pyb::array& a) {
  std::string s = "(";
  for (pyb::ssize_t i = 0; i < a.ndim(); ++i) s += (i ? ", " : "") + std::to_string(a.shape(i));
  return s + (a.ndim() == 1 ? ",)" : ")");
}

pyb::array as_array(const pyb::handle& obj, const std::string& arg) {
  if (!pyb::isinstance<pyb::array>(obj))
    throw pyb::value_error(arg + ": expected a numpy array, got " + std::string(pyb::str(obj.get_type().attr("__name__"))));
  return pyb::reinterpret_borrow<pyb::array>(obj);
}

void check_contiguous(const pyb::array& a, const std::string& arg) {
  if (!(a.flags() & pyb::array::c_style))
    throw pyb::value_error(arg + ": the array is not C-contiguous (a slice or a transpose); pass "
                                 "numpy.ascontiguousarray(" + arg + ")");
}

}  // namespace

io::Image image_from_array(const pyb::handle& obj, const std::string& arg) {
  const pyb::array a = as_array(obj, arg);
  const bool u8 = a.dtype().is(pyb::dtype::of<uint8_t>());
  if (!u8 && !a.dtype().is(pyb::dtype::of<float>()))
    throw pyb::value_error(arg + ": dtype " + std::string(pyb::str(a.dtype())) +
                           " is not supported; give float32 in [0, 1] or uint8");
  if (a.ndim() != 3 || a.shape(2) != 3 || a.shape(0) < 1 || a.shape(1) < 1)
    throw pyb::value_error(arg + ": expected an H x W x 3 image, got shape " + shape_text(a));
  check_contiguous(a, arg);
  io::Image img;
  img.height = int(a.shape(0));
  img.width = int(a.shape(1));
  const size_t plane = size_t(img.width) * img.height;
  img.data.resize(3 * plane);
  if (u8) {
    const uint8_t* p = static_cast<const uint8_t*>(a.data());
    for (size_t i = 0; i < plane; ++i)
      for (int c = 0; c < 3; ++c) img.data[c * plane + i] = p[3 * i + c] / 255.0f;
    return img;
  }
  const float* p = static_cast<const float*>(a.data());
  for (size_t i = 0; i < plane; ++i)
    for (int c = 0; c < 3; ++c) {
      const float v = p[3 * i + c];
      if (!std::isfinite(v))
        throw pyb::value_error(arg + ": holds NaN or infinity (at pixel " + std::to_string(i / img.width) + ", " +
                               std::to_string(i % img.width) + ")");
      if (v < 0.0f || v > 1.0f)
        throw pyb::value_error(arg + ": float32 images must lie in [0, 1]; found " + std::to_string(v));
      img.data[c * plane + i] = v;
    }
  return img;
}

pyb::array_t<float> to_array(std::vector<float>&& values, int height, int width, int channels) {
  auto* owned = new std::vector<float>(std::move(values));
  pyb::capsule base(owned, [](void* p) { delete static_cast<std::vector<float>*>(p); });
  std::vector<pyb::ssize_t> shape = {height, width};
  if (channels > 1) shape.push_back(channels);
  return pyb::array_t<float>(shape, owned->data(), base);
}

pyb::array_t<float, pyb::array::c_style> float_array(const pyb::handle& obj, const std::vector<long>& shape,
                                                     const std::string& arg) {
  const pyb::array a = as_array(obj, arg);
  if (!a.dtype().is(pyb::dtype::of<float>()) && !a.dtype().is(pyb::dtype::of<double>()))
    throw pyb::value_error(arg + ": dtype " + std::string(pyb::str(a.dtype())) + " is not supported; give float32");
  bool same = a.ndim() == pyb::ssize_t(shape.size());
  for (size_t i = 0; same && i < shape.size(); ++i) same = a.shape(pyb::ssize_t(i)) == shape[i];
  if (!same) {
    std::string want = "(";
    for (size_t i = 0; i < shape.size(); ++i) want += (i ? ", " : "") + std::to_string(shape[i]);
    throw pyb::value_error(arg + ": expected shape " + want + "), got " + shape_text(a));
  }
  check_contiguous(a, arg);
  // float64 (numpy's default for literals such as np.eye(4)[:3]) converts; float32 is read in place.
  const pyb::object f32 = a.dtype().is(pyb::dtype::of<float>()) ? pyb::object(a) : a.attr("astype")("float32");
  auto f = pyb::reinterpret_borrow<pyb::array_t<float, pyb::array::c_style>>(f32);
  for (pyb::ssize_t i = 0; i < f.size(); ++i)
    if (!std::isfinite(f.data()[i])) throw pyb::value_error(arg + ": holds NaN or infinity");
  return f;
}

}  // namespace stylerf::py
