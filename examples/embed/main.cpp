// The smallest program that embeds libstylerf: pick a device, run a GEMM, read the result back.
#include <iostream>

#include "host/gemm.hpp"
#include "host/runtime.hpp"
#include "host/tensor.hpp"

int main() {
  using namespace stylerf::host;
  try {
    Runtime& rt = Runtime::init();  // STYLERF_DEVICE picks the device
    std::cout << "device: " << rt.device().describe() << "\n";
    Tensor a = Tensor::from_host({1, 2, 3, 4, 5, 6}, {2, 3});
    Tensor b = Tensor::from_host({1, 0, 0, 1, 1, 1}, {3, 2});
    Tensor c = Tensor::zeros({2, 2});
    matmul(a, Trans::No, b, Trans::No, c);
    auto v = c.to_host();
    std::cout << "[[" << v[0] << ", " << v[1] << "], [" << v[2] << ", " << v[3] << "]]\n";  // [[4, 5], [10, 11]]
    const bool ok = v[0] == 4 && v[1] == 5 && v[2] == 10 && v[3] == 11;
    Runtime::shutdown();  // drain the queue before exit (see host/runtime.hpp)
    return ok ? 0 : 1;
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 1;
  }
}
