// Device tensors: a shape and a contiguous float32 buffer on the runtime's device.
//
// Copies are shallow (they share the buffer, like a handle); clone() copies the data. There are no
// strided views: kernels take whole tensors plus explicit offsets where they need them, which keeps
// every kernel's indexing obvious.
#pragma once
#include <CL/cl.h>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace stylerf::host {

using Shape = std::vector<int64_t>;
std::string shape_str(const Shape& s);  // "[2, 3, 4]"
int64_t shape_numel(const Shape& s);

// RAII owner of a cl_mem.
class Buffer {
 public:
  Buffer(size_t bytes, const std::string& what);
  ~Buffer();
  Buffer(const Buffer&) = delete;
  Buffer& operator=(const Buffer&) = delete;
  cl_mem mem() const { return mem_; }
  size_t bytes() const { return bytes_; }

 private:
  cl_mem mem_ = nullptr;
  size_t bytes_ = 0;
};

class Tensor {
 public:
  Tensor() = default;
  // Uninitialised device memory of the given shape. `what` names it in allocation errors.
  explicit Tensor(Shape shape, const std::string& what = "tensor");
  static Tensor zeros(Shape shape, const std::string& what = "tensor");
  static Tensor full(Shape shape, float value, const std::string& what = "tensor");
  static Tensor from_host(const std::vector<float>& data, Shape shape, const std::string& what = "tensor");

  std::vector<float> to_host() const;
  void upload(const std::vector<float>& data);
  void fill(float value);
  void zero() { fill(0.0f); }
  void copy_from(const Tensor& other);  // same numel; device-side copy

  bool defined() const { return static_cast<bool>(buffer_); }
  const Shape& shape() const { return shape_; }
  int ndim() const { return static_cast<int>(shape_.size()); }
  int64_t dim(int i) const;  // negative counts from the end
  int64_t numel() const { return shape_numel(shape_); }
  size_t bytes() const { return static_cast<size_t>(numel()) * sizeof(float); }
  cl_mem mem() const;

  Tensor reshape(Shape shape) const;  // same buffer, same numel
  Tensor clone() const;
  bool same_buffer(const Tensor& other) const { return buffer_ == other.buffer_; }

 private:
  Shape shape_;
  std::shared_ptr<Buffer> buffer_;
};

// Throws an Error "<op>: <name> has shape [..], expected [..]" when shapes differ.
void expect_shape(const Tensor& t, const Shape& expected, const char* op, const char* name);

}  // namespace stylerf::host
