#include "host/tensor.hpp"

#include <sstream>

#include "host/error.hpp"
#include "host/runtime.hpp"

namespace stylerf::host {

std::string shape_str(const Shape& s) {
  std::ostringstream o;
  o << "[";
  for (size_t i = 0; i < s.size(); ++i) o << (i ? ", " : "") << s[i];
  o << "]";
  return o.str();
}

int64_t shape_numel(const Shape& s) {
  int64_t n = 1;
  for (int64_t d : s) {
    if (d < 0) throw Error("negative dimension in shape " + shape_str(s));
    n *= d;
  }
  return n;
}

Buffer::Buffer(size_t bytes, const std::string& what) : bytes_(bytes) {
  mem_ = Runtime::instance().allocate(bytes, what);
}

Buffer::~Buffer() {
  if (!mem_) return;
  if (Runtime::initialised())
    Runtime::instance().release(mem_, bytes_);
  else
    clReleaseMemObject(mem_);  // runtime already gone (process exit)
}

Tensor::Tensor(Shape shape, const std::string& what) : shape_(std::move(shape)) {
  int64_t n = shape_numel(shape_);
  // Kernels index with 32-bit ints; refuse what they cannot address rather than wrap around.
  if (n >= (int64_t(1) << 31))
    throw Error("tensor " + what + " of shape " + shape_str(shape_) + " has more than 2^31 elements");
  buffer_ = std::make_shared<Buffer>(static_cast<size_t>(n) * sizeof(float), what + " " + shape_str(shape_));
}

Tensor Tensor::zeros(Shape shape, const std::string& what) {
  Tensor t(std::move(shape), what);
  t.fill(0.0f);
  return t;
}

Tensor Tensor::full(Shape shape, float value, const std::string& what) {
  Tensor t(std::move(shape), what);
  t.fill(value);
  return t;
}

Tensor Tensor::from_host(const std::vector<float>& data, Shape shape, const std::string& what) {
  Tensor t(std::move(shape), what);
  t.upload(data);
  return t;
}

cl_mem Tensor::mem() const {
  if (!buffer_) throw Error("use of an undefined tensor");
  return buffer_->mem();
}

int64_t Tensor::dim(int i) const {
  int n = ndim();
  int j = i < 0 ? i + n : i;
  if (j < 0 || j >= n) throw Error("dimension " + std::to_string(i) + " out of range for shape " + shape_str(shape_));
  return shape_[j];
}

std::vector<float> Tensor::to_host() const {
  std::vector<float> out(static_cast<size_t>(numel()));
  if (out.empty()) return out;
  check(clEnqueueReadBuffer(Runtime::instance().queue(), mem(), CL_TRUE, 0, bytes(), out.data(), 0, nullptr, nullptr),
        "clEnqueueReadBuffer", "tensor " + shape_str(shape_));
  return out;
}

void Tensor::upload(const std::vector<float>& data) {
  if (static_cast<int64_t>(data.size()) != numel())
    throw Error("upload of " + std::to_string(data.size()) + " floats into a tensor of shape " + shape_str(shape_));
  if (data.empty()) return;
  check(clEnqueueWriteBuffer(Runtime::instance().queue(), mem(), CL_TRUE, 0, bytes(), data.data(), 0, nullptr, nullptr),
        "clEnqueueWriteBuffer", "tensor " + shape_str(shape_));
}

void Tensor::fill(float value) {
  if (numel() == 0) return;
  check(clEnqueueFillBuffer(Runtime::instance().queue(), mem(), &value, sizeof(float), 0, bytes(), 0, nullptr, nullptr),
        "clEnqueueFillBuffer", "tensor " + shape_str(shape_));
}

void Tensor::copy_from(const Tensor& other) {
  if (other.numel() != numel())
    throw Error("copy of a tensor of shape " + shape_str(other.shape_) + " into one of shape " + shape_str(shape_));
  if (numel() == 0) return;
  check(clEnqueueCopyBuffer(Runtime::instance().queue(), other.mem(), mem(), 0, 0, bytes(), 0, nullptr, nullptr),
        "clEnqueueCopyBuffer", "tensor " + shape_str(shape_));
}

Tensor Tensor::reshape(Shape shape) const {
  if (shape_numel(shape) != numel())
    throw Error("cannot reshape " + shape_str(shape_) + " to " + shape_str(shape));
  Tensor t = *this;
  t.shape_ = std::move(shape);
  return t;
}

Tensor Tensor::clone() const {
  Tensor t(shape_, "clone");
  t.copy_from(*this);
  return t;
}

void expect_shape(const Tensor& t, const Shape& expected, const char* op, const char* name) {
  if (t.shape() != expected)
    throw Error(std::string(op) + ": " + name + " has shape " + shape_str(t.shape()) + ", expected " +
                shape_str(expected));
}

}  // namespace stylerf::host
