// Device tensors: a shape, an element type (host/dtype.hpp) and a contiguous buffer on the runtime's device.
//
// Copies are shallow (they share the buffer, like a handle); clone() copies the data. There are no
// strided views: kernels take whole tensors plus explicit offsets where they need them, which keeps
// every kernel's indexing obvious.
//
// The float API is the default (a tensor made without a dtype is F32). Reading or writing a tensor as the
// wrong type is an error naming the tensor, never a reinterpretation of its bits.
#pragma once
#include <CL/cl.h>

#include <cstdint>
#include <initializer_list>
#include <memory>
#include <string>
#include <type_traits>
#include <vector>

#include "host/dtype.hpp"

namespace stylerf::host {

using Shape = std::vector<int64_t>;
std::string shape_str(const Shape& s);  // "[2, 3, 4]"
int64_t shape_numel(const Shape& s);

// RAII owner of a cl_mem. `what` names it (tensors use it in dtype errors); `detail` is added to
// allocation-failure messages only (a tensor's shape).
class Buffer {
 public:
  Buffer(size_t bytes, const std::string& what, const std::string& detail = "");
  ~Buffer();
  Buffer(const Buffer&) = delete;
  Buffer& operator=(const Buffer&) = delete;
  cl_mem mem() const { return mem_; }
  size_t bytes() const { return bytes_; }
  const std::string& what() const { return what_; }

 private:
  cl_mem mem_ = nullptr;
  size_t bytes_ = 0;
  std::string what_;
};

// Host element types with a non-float dtype: the typed overloads below accept exactly these.
template <class T>
using EnableIntData = std::enable_if_t<std::is_same_v<T, int32_t> || std::is_same_v<T, uint8_t>>;

class Tensor {
 public:
  Tensor() = default;
  // Uninitialised device memory of the given shape. `what` names it in errors (allocation, dtype).
  explicit Tensor(Shape shape, const std::string& what = "tensor");  // F32
  Tensor(Shape shape, DType dtype, const std::string& what = "tensor");
  static Tensor zeros(Shape shape, const std::string& what = "tensor");  // F32
  static Tensor zeros(Shape shape, DType dtype, const std::string& what = "tensor");
  static Tensor full(Shape shape, float value, const std::string& what = "tensor");  // F32
  static Tensor from_host(const std::vector<float>& data, Shape shape, const std::string& what = "tensor");
  // int32_t data gives an I32 tensor, uint8_t data a U8 one. A template rather than overloads on purpose: a
  // braced list such as from_host({1, 2, 3}, {3}) cannot deduce T, so it still means the float overload.
  template <class T, class = EnableIntData<T>>
  static Tensor from_host(const std::vector<T>& data, Shape shape, const std::string& what = "tensor");

  // Each reader and writer checks the dtype: to_host() is for F32 tensors only.
  std::vector<float> to_host() const;
  std::vector<int32_t> to_host_i32() const;
  std::vector<uint8_t> to_host_u8() const;
  void upload(const std::vector<float>& data);
  template <class T, class = EnableIntData<T>>
  void upload(const std::vector<T>& data) {
    write(data.data(), data.size(), dtype_of<T>());
  }
  // Raw bytes [offset, offset + n) of the buffer, any dtype: for filling or reading a large tensor piece by
  // piece (one view of the F16 target maps) without a host copy of the whole. Out-of-range spans throw.
  void write_bytes(size_t offset, const void* data, size_t n);
  void read_bytes(size_t offset, void* data, size_t n) const;
  void fill(float value);  // F32 only
  void zero();             // any dtype: all-zero bits are 0 in each
  void copy_from(const Tensor& other);  // same dtype and numel; device-side copy

  bool defined() const { return static_cast<bool>(buffer_); }
  DType dtype() const { return dtype_; }
  const std::string& name() const;  // the `what` it was made with ("undefined tensor" when undefined)
  const Shape& shape() const { return shape_; }
  int ndim() const { return static_cast<int>(shape_.size()); }
  int64_t dim(int i) const;  // negative counts from the end
  int64_t numel() const { return shape_numel(shape_); }
  size_t element_size() const { return dtype_size(dtype_); }
  size_t bytes() const { return static_cast<size_t>(numel()) * element_size(); }
  cl_mem mem() const;

  Tensor reshape(Shape shape) const;  // same buffer, same numel, same dtype
  Tensor clone() const;               // same dtype and name
  bool same_buffer(const Tensor& other) const { return buffer_ == other.buffer_; }

 private:
  void write(const void* data, size_t count, DType type);
  void read(void* data, DType type, const char* op) const;

  Shape shape_;
  DType dtype_ = DType::F32;
  std::shared_ptr<Buffer> buffer_;
};

template <class T, class>
Tensor Tensor::from_host(const std::vector<T>& data, Shape shape, const std::string& what) {
  Tensor t(std::move(shape), dtype_of<T>(), what);
  t.upload(data);
  return t;
}

// Throws an Error "<op>: <name> has shape [..], expected [..]" when shapes differ.
void expect_shape(const Tensor& t, const Shape& expected, const char* op, const char* name);
// Throws an Error "<op>: <name> ('<tensor name>' [..]) has dtype i32, expected f32" (or "... is undefined")
// unless t is defined and of one of the allowed dtypes.
void expect_dtype(const Tensor& t, std::initializer_list<DType> allowed, const char* op, const char* name);
inline void expect_dtype(const Tensor& t, DType allowed, const char* op, const char* name) {
  expect_dtype(t, {allowed}, op, name);
}
// Both checks, dtype first (a wrong-typed argument usually has the right shape too).
void expect_shape(const Tensor& t, const Shape& expected, DType dtype, const char* op, const char* name);

}  // namespace stylerf::host
