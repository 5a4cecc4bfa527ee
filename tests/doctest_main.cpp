#define DOCTEST_CONFIG_IMPLEMENT
#include <doctest/doctest.h>

#include <iostream>

#include "host/runtime.hpp"

int main(int argc, char** argv) {
  // One device for the whole suite; STYLERF_DEVICE picks it like the CLI does.
  auto& rt = stylerf::host::Runtime::init();
  std::cout << "device: " << rt.device().describe() << std::endl;
  doctest::Context ctx(argc, argv);
  int rc = ctx.run();
  stylerf::host::Runtime::shutdown();
  return rc;
}
