// numpy <-> the library's images, with the checks every entry point shares: a bad array is a ValueError
// that names the argument (wrong dtype, shape, non-contiguous memory, NaN or infinity, values outside
// [0, 1]).
#pragma once
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <string>
#include <vector>

#include "lib/io/image.hpp"

namespace stylerf::py {

namespace pyb = pybind11;

// An H x W x 3 image, float32 in [0, 1] or uint8 (divided by 255), C-contiguous, as a planar io::Image.
// The library's images are planar and numpy's interleaved, so this one copy is the layout change itself.
io::Image image_from_array(const pyb::handle& obj, const std::string& arg);

// Interleaved [H*W*C] floats as an H x W x C float32 array that owns them: no copy (the vector moves into
// the array's base object). C == 1 gives an H x W array.
pyb::array_t<float> to_array(std::vector<float>&& values, int height, int width, int channels);

// A C-contiguous float32 array of `shape` (no copy: the returned view reads numpy's memory as is).
pyb::array_t<float, pyb::array::c_style> float_array(const pyb::handle& obj, const std::vector<long>& shape,
                                                     const std::string& arg);

}  // namespace stylerf::py
