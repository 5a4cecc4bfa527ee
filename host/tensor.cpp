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

Buffer::Buffer(size_t bytes, const std::string& what, const std::string& detail) : bytes_(bytes), what_(what) {
  mem_ = Runtime::instance().allocate(bytes, detail.empty() ? what : what + " " + detail);
}

Buffer::~Buffer() {
  if (!mem_) return;
  // A buffer that outlives the runtime belongs to a static cache (e.g. the grid scatter's scratch)
  // destroyed at process exit, after Runtime::shutdown(): it is left to the OS. Releasing it would call the
  // driver from a static destructor, after the driver's own thread-locals and statics may be gone
  // (Oclgrind's runtime wrote to its freed per-thread call stack there: "corrupted double-linked list").
  if (Runtime::initialised()) Runtime::instance().release(mem_, bytes_);
}

namespace {

// "'ray sample counts' [4096] i32": how errors name a tensor.
std::string describe(const Tensor& t) {
  return "'" + t.name() + "' " + shape_str(t.shape()) + " " + dtype_name(t.dtype());
}

// Tensor methods check their own dtype with the same wording as the ops' checks.
void expect_own_dtype(const Tensor& t, DType want, const char* op) {
  if (t.dtype() != want)
    throw Error(std::string(op) + ": tensor '" + t.name() + "' " + shape_str(t.shape()) + " has dtype " +
                dtype_name(t.dtype()) + ", not " + dtype_name(want));
}

}  // namespace

Tensor::Tensor(Shape shape, const std::string& what) : Tensor(std::move(shape), DType::F32, what) {}

Tensor::Tensor(Shape shape, DType dtype, const std::string& what) : shape_(std::move(shape)), dtype_(dtype) {
  int64_t n = shape_numel(shape_);
  // Kernels index with 32-bit ints; refuse what they cannot address rather than wrap around.
  if (n >= (int64_t(1) << 31))
    throw Error("tensor " + what + " of shape " + shape_str(shape_) + " has more than 2^31 elements");
  buffer_ = std::make_shared<Buffer>(static_cast<size_t>(n) * dtype_size(dtype), what,
                                     shape_str(shape_) + " " + dtype_name(dtype));
}

Tensor Tensor::zeros(Shape shape, const std::string& what) { return zeros(std::move(shape), DType::F32, what); }

Tensor Tensor::zeros(Shape shape, DType dtype, const std::string& what) {
  Tensor t(std::move(shape), dtype, what);
  t.zero();
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

const std::string& Tensor::name() const {
  static const std::string undefined = "undefined tensor";
  return buffer_ ? buffer_->what() : undefined;
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

void Tensor::read(void* data, DType type, const char* op) const {
  expect_own_dtype(*this, type, op);
  if (numel() == 0) return;
  check(clEnqueueReadBuffer(Runtime::instance().queue(), mem(), CL_TRUE, 0, bytes(), data, 0, nullptr, nullptr),
        "clEnqueueReadBuffer", "tensor " + describe(*this));
}

std::vector<float> Tensor::to_host() const {
  std::vector<float> out(static_cast<size_t>(numel()));
  read(out.data(), DType::F32, "to_host");
  return out;
}

std::vector<int32_t> Tensor::to_host_i32() const {
  std::vector<int32_t> out(static_cast<size_t>(numel()));
  read(out.data(), DType::I32, "to_host_i32");
  return out;
}

std::vector<uint8_t> Tensor::to_host_u8() const {
  std::vector<uint8_t> out(static_cast<size_t>(numel()));
  read(out.data(), DType::U8, "to_host_u8");
  return out;
}

void Tensor::write(const void* data, size_t count, DType type) {
  expect_own_dtype(*this, type, (std::string("upload of ") + dtype_name(type) + " data").c_str());
  if (static_cast<int64_t>(count) != numel())
    throw Error("upload of " + std::to_string(count) + " values into tensor " + describe(*this));
  if (count == 0) return;
  check(clEnqueueWriteBuffer(Runtime::instance().queue(), mem(), CL_TRUE, 0, bytes(), data, 0, nullptr, nullptr),
        "clEnqueueWriteBuffer", "tensor " + describe(*this));
}

namespace {
void expect_span(const Tensor& t, size_t offset, size_t n, const char* op) {
  if (offset > t.bytes() || n > t.bytes() - offset)
    throw Error(std::string(op) + ": bytes [" + std::to_string(offset) + ", " + std::to_string(offset + n) +
                ") lie outside tensor " + describe(t) + " (" + std::to_string(t.bytes()) + " bytes)");
}
}  // namespace

void Tensor::write_bytes(size_t offset, const void* data, size_t n) {
  expect_span(*this, offset, n, "write_bytes");
  if (n == 0) return;
  check(clEnqueueWriteBuffer(Runtime::instance().queue(), mem(), CL_TRUE, offset, n, data, 0, nullptr, nullptr),
        "clEnqueueWriteBuffer", "tensor " + describe(*this));
}

void Tensor::read_bytes(size_t offset, void* data, size_t n) const {
  expect_span(*this, offset, n, "read_bytes");
  if (n == 0) return;
  check(clEnqueueReadBuffer(Runtime::instance().queue(), mem(), CL_TRUE, offset, n, data, 0, nullptr, nullptr),
        "clEnqueueReadBuffer", "tensor " + describe(*this));
}

void Tensor::upload(const std::vector<float>& data) { write(data.data(), data.size(), DType::F32); }

void Tensor::fill(float value) {
  expect_own_dtype(*this, DType::F32, "fill");
  if (numel() == 0) return;
  check(clEnqueueFillBuffer(Runtime::instance().queue(), mem(), &value, sizeof(float), 0, bytes(), 0, nullptr, nullptr),
        "clEnqueueFillBuffer", "tensor " + describe(*this));
}

void Tensor::zero() {
  if (numel() == 0) return;
  const uint32_t pattern = 0;  // one element's worth of zero bytes (1 or 4)
  check(clEnqueueFillBuffer(Runtime::instance().queue(), mem(), &pattern, element_size(), 0, bytes(), 0, nullptr,
                            nullptr),
        "clEnqueueFillBuffer", "tensor " + describe(*this));
}

void Tensor::copy_from(const Tensor& other) {
  if (other.dtype_ != dtype_ || other.numel() != numel())
    throw Error("copy_from: cannot copy tensor " + describe(other) + " into tensor " + describe(*this));
  if (numel() == 0) return;
  check(clEnqueueCopyBuffer(Runtime::instance().queue(), other.mem(), mem(), 0, 0, bytes(), 0, nullptr, nullptr),
        "clEnqueueCopyBuffer", "tensor " + describe(*this));
}

Tensor Tensor::reshape(Shape shape) const {
  if (shape_numel(shape) != numel())
    throw Error("cannot reshape " + shape_str(shape_) + " to " + shape_str(shape));
  Tensor t = *this;
  t.shape_ = std::move(shape);
  return t;
}

Tensor Tensor::clone() const {
  Tensor t(shape_, dtype_, name());
  t.copy_from(*this);
  return t;
}

void expect_shape(const Tensor& t, const Shape& expected, const char* op, const char* name) {
  if (t.shape() != expected)
    throw Error(std::string(op) + ": " + name + " has shape " + shape_str(t.shape()) + ", expected " +
                shape_str(expected));
}

void expect_dtype(const Tensor& t, std::initializer_list<DType> allowed, const char* op, const char* name) {
  if (!t.defined()) throw Error(std::string(op) + ": " + name + " is undefined");
  for (DType d : allowed)
    if (t.dtype() == d) return;
  std::string want;
  for (DType d : allowed) want += (want.empty() ? "" : " or ") + std::string(dtype_name(d));
  throw Error(std::string(op) + ": " + name + " ('" + t.name() + "' " + shape_str(t.shape()) + ") has dtype " +
              dtype_name(t.dtype()) + ", expected " + want);
}

void expect_shape(const Tensor& t, const Shape& expected, DType dtype, const char* op, const char* name) {
  expect_dtype(t, dtype, op, name);
  expect_shape(t, expected, op, name);
}

}  // namespace stylerf::host
