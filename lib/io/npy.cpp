#include "lib/io/npy.hpp"

#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "host/error.hpp"
#include "host/files.hpp"

namespace stylerf::io {

using host::Error;

namespace {

// The header is a Python dict literal like {'descr': '<f8', 'fortran_order': False, 'shape': (20, 17), }.
// We read the three keys by hand instead of evaluating Python.
std::string dict_value(const std::string& header, const std::string& key, const std::string& path) {
  size_t k = header.find("'" + key + "'");
  if (k == std::string::npos) k = header.find("\"" + key + "\"");
  if (k == std::string::npos) throw Error("npy file " + path + ": header has no '" + key + "' entry: " + header);
  size_t colon = header.find(':', k);
  if (colon == std::string::npos) throw Error("npy file " + path + ": malformed header: " + header);
  size_t v = header.find_first_not_of(" ", colon + 1);
  if (v == std::string::npos) throw Error("npy file " + path + ": malformed header: " + header);
  if (header[v] == '(') {
    size_t end = header.find(')', v);
    if (end == std::string::npos) throw Error("npy file " + path + ": malformed shape in header: " + header);
    return header.substr(v, end - v + 1);
  }
  if (header[v] == '\'' || header[v] == '"') {
    size_t end = header.find(header[v], v + 1);
    if (end == std::string::npos) throw Error("npy file " + path + ": malformed header: " + header);
    return header.substr(v + 1, end - v - 1);
  }
  size_t end = header.find_first_of(",}", v);
  return header.substr(v, end - v);
}

std::vector<size_t> parse_shape(const std::string& tuple, const std::string& path) {
  std::vector<size_t> shape;
  if (tuple.size() < 2 || tuple.front() != '(' || tuple.back() != ')')
    throw Error("npy file " + path + ": the shape '" + tuple + "' is not a tuple");
  std::string inner = tuple.substr(1, tuple.size() - 2);
  std::stringstream ss(inner);
  std::string item;
  while (std::getline(ss, item, ',')) {
    size_t a = item.find_first_not_of(" "), b = item.find_last_not_of(" L");
    if (a == std::string::npos) continue;  // trailing comma of a 1-tuple
    std::string num = item.substr(a, b - a + 1);
    char* end = nullptr;
    long long v = std::strtoll(num.c_str(), &end, 10);
    if (end == num.c_str() || *end != '\0' || v < 0)
      throw Error("npy file " + path + ": bad dimension '" + num + "' in shape " + tuple);
    shape.push_back(size_t(v));
  }
  return shape;
}

std::string shape_text(const std::vector<size_t>& s) {
  std::string t = "(";
  for (size_t i = 0; i < s.size(); ++i) t += (i ? ", " : "") + std::to_string(s[i]);
  return t + (s.size() == 1 ? ",)" : ")");
}

}  // namespace

NpyArray read_npy(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw Error("npy file " + path + " does not exist");
  const std::string bytes = host::read_file(path);
  static const char magic[] = "\x93NUMPY";
  if (bytes.size() < 10 || std::memcmp(bytes.data(), magic, 6) != 0)
    throw Error("npy file " + path + " is not a NumPy .npy file (bad magic bytes)");
  const int major = static_cast<unsigned char>(bytes[6]);
  size_t header_len = 0, header_start = 0;
  if (major == 1) {
    header_len = static_cast<unsigned char>(bytes[8]) | (size_t(static_cast<unsigned char>(bytes[9])) << 8);
    header_start = 10;
  } else if (major == 2 || major == 3) {
    if (bytes.size() < 12) throw Error("npy file " + path + " is truncated (header)");
    for (int i = 0; i < 4; ++i) header_len |= size_t(static_cast<unsigned char>(bytes[8 + i])) << (8 * i);
    header_start = 12;
  } else {
    throw Error("npy file " + path + ": unsupported format version " + std::to_string(major));
  }
  if (header_start + header_len > bytes.size()) throw Error("npy file " + path + " is truncated (header)");
  const std::string header = bytes.substr(header_start, header_len);

  NpyArray a;
  a.dtype = dict_value(header, "descr", path);
  const std::string fortran = dict_value(header, "fortran_order", path);
  if (fortran.find("True") != std::string::npos)
    throw Error("npy file " + path + " is stored in Fortran order; only C order is supported");
  a.shape = parse_shape(dict_value(header, "shape", path), path);

  size_t count = 1;
  for (size_t d : a.shape) {
    // A corrupt header may claim dimensions whose product overflows: refuse it rather than wrap around.
    if (d != 0 && count > (size_t(1) << 40) / d)
      throw Error("npy file " + path + ": shape " + shape_text(a.shape) + " is impossibly large (corrupt header)");
    count *= d;
  }
  size_t item = 0;
  if (a.dtype == "<f8" || a.dtype == "<i8") item = 8;
  else if (a.dtype == "<f4" || a.dtype == "<i4") item = 4;
  else
    throw Error("npy file " + path + ": dtype '" + a.dtype +
                "' is not supported (expected little-endian float64 '<f8' or float32 '<f4')");
  const size_t payload = header_start + header_len;
  if (bytes.size() - payload != count * item)
    throw Error("npy file " + path + ": payload is " + std::to_string(bytes.size() - payload) + " bytes but shape " +
                shape_text(a.shape) + " of " + a.dtype + " needs " + std::to_string(count * item) +
                " (truncated or corrupt file)");

  a.data.resize(count);
  const char* p = bytes.data() + payload;
  for (size_t i = 0; i < count; ++i) {
    if (a.dtype == "<f8") { double v; std::memcpy(&v, p + 8 * i, 8); a.data[i] = v; }
    else if (a.dtype == "<f4") { float v; std::memcpy(&v, p + 4 * i, 4); a.data[i] = v; }
    else if (a.dtype == "<i8") { int64_t v; std::memcpy(&v, p + 8 * i, 8); a.data[i] = double(v); }
    else { int32_t v; std::memcpy(&v, p + 4 * i, 4); a.data[i] = double(v); }
  }
  return a;
}

NpyArray read_npy_checked(const std::string& path, const std::vector<long>& expect_dims, const std::string& what) {
  NpyArray a = read_npy(path);
  bool ok = a.shape.size() == expect_dims.size();
  for (size_t i = 0; ok && i < expect_dims.size(); ++i)
    if (expect_dims[i] >= 0 && size_t(expect_dims[i]) != a.shape[i]) ok = false;
  if (!ok) {
    std::string want = "(";
    for (size_t i = 0; i < expect_dims.size(); ++i)
      want += (i ? ", " : "") + (expect_dims[i] < 0 ? std::string("N") : std::to_string(expect_dims[i]));
    throw Error("npy file " + path + ": " + what + " has shape " + shape_text(a.shape) + ", expected " + want + ")");
  }
  return a;
}

void write_npy_f32(const std::string& path, const std::vector<size_t>& shape, const std::vector<float>& data) {
  size_t count = 1;
  for (size_t d : shape) count *= d;
  if (count != data.size())
    throw Error("write_npy_f32 " + path + ": shape " + shape_text(shape) + " does not match " +
                std::to_string(data.size()) + " values");
  std::string header = "{'descr': '<f4', 'fortran_order': False, 'shape': " + shape_text(shape) + ", }";
  // Pad with spaces so magic + length + header + '\n' is a multiple of 64, as numpy does.
  size_t total = 10 + header.size() + 1;
  header.append((64 - total % 64) % 64, ' ');
  header += '\n';
  std::string out = std::string("\x93NUMPY\x01\x00", 8);
  out += char(header.size() & 0xff);
  out += char((header.size() >> 8) & 0xff);
  out += header;
  out.append(reinterpret_cast<const char*>(data.data()), data.size() * sizeof(float));
  host::write_file_atomic(path, out);
}

}  // namespace stylerf::io
