#include <sys/stat.h>

#include "fuzz/fuzz_common.hpp"
#include "lib/io/npy.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string p = fuzz::write("a.npy", data, size);
  fuzz::expect_clean([&] { stylerf::io::read_npy(p); });
  fuzz::expect_clean([&] { stylerf::io::read_npy_checked(p, {-1, 17}, "poses_bounds"); });
  return 0;
}
