// NumPy .npy files: a reader for the small numeric arrays datasets ship (LLFF's poses_bounds.npy) and a
// float32 writer for debug outputs. Only what those need: little-endian float64/float32 (and int32/int64
// read as numbers), C order. Everything else is refused with an error that names the file and the reason.
#pragma once
#include <cstddef>
#include <string>
#include <vector>

namespace stylerf::io {

struct NpyArray {
  std::string dtype;               // as in the header: "<f8", "<f4", "<i4", "<i8"
  std::vector<size_t> shape;       // e.g. {20, 17}
  std::vector<double> data;        // every element converted to double, C (row-major) order
  size_t size() const { return data.size(); }
};

// Reads and validates the whole file (magic, version 1/2/3, header dict, payload length).
NpyArray read_npy(const std::string& path);

// Like read_npy, then checks the shape: expect_rank dimensions, and each entry of expect_dims that is
// not -1 must match. `what` names the content in errors ("poses_bounds").
NpyArray read_npy_checked(const std::string& path, const std::vector<long>& expect_dims, const std::string& what);

// Writes a little-endian float32 C-order array atomically (version 1.0 header, 64-byte aligned).
void write_npy_f32(const std::string& path, const std::vector<size_t>& shape, const std::vector<float>& data);

}  // namespace stylerf::io
