#include <sys/stat.h>

#include "fuzz/fuzz_common.hpp"
#include "lib/io/checkpoint.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string p = fuzz::write("a.ckpt", data, size);
  fuzz::expect_clean([&] { stylerf::io::load_checkpoint(p, ""); });
  fuzz::expect_clean([&] { stylerf::io::load_checkpoint(p, "density"); });
  return 0;
}
