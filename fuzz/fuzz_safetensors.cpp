#include <sys/stat.h>

#include "fuzz/fuzz_common.hpp"
#include "lib/io/safetensors.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string p = fuzz::write("a.safetensors", data, size);
  fuzz::expect_clean([&] {
    const auto st = stylerf::io::SafeTensors::load(p);
    for (const auto& n : st.names()) st.get(n);
  });
  return 0;
}
