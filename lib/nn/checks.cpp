#include "lib/nn/checks.hpp"

#include <climits>
#include <string>

#include "host/error.hpp"

namespace stylerf::nn {

using host::Error;

int expect_flat(const host::Tensor& x, const char* op, const char* name) {
  if (!x.defined()) throw Error(std::string(op) + ": " + name + " is undefined");
  // Kernels index with int (cheaper address arithmetic on every device); refuse what would overflow.
  if (x.numel() > INT_MAX)
    throw Error(std::string(op) + ": " + name + " has " + std::to_string(x.numel()) + " elements, more than " +
                std::to_string(INT_MAX) + " that int indexing allows");
  return static_cast<int>(x.numel());
}

ChannelDims expect_nchw(const host::Tensor& x, const char* op, const char* name) {
  expect_flat(x, op, name);
  if (x.ndim() != 4)
    throw Error(std::string(op) + ": " + name + " must be 4-D [N,C,H,W], got shape " + host::shape_str(x.shape()));
  if (x.numel() == 0)
    throw Error(std::string(op) + ": " + name + " is empty (shape " + host::shape_str(x.shape()) + ")");
  ChannelDims d;
  d.n = x.dim(0);
  d.c = x.dim(1);
  d.h = x.dim(2);
  d.w = x.dim(3);
  d.nc = static_cast<int>(d.n * d.c);
  d.hw = static_cast<int>(d.h * d.w);
  return d;
}

}  // namespace stylerf::nn
