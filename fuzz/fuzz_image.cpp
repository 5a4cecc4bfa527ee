#include <sys/stat.h>

#include "fuzz/fuzz_common.hpp"
#include "lib/io/image.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  // A tiny header may claim gigapixels: load_image refuses those before allocating (kMaxImagePixels).
  const std::string p = fuzz::write("a.img", data, size);
  fuzz::expect_clean([&] { stylerf::io::image_unreadable_reason(p); });
  fuzz::expect_clean([&] {
    std::vector<float> alpha;
    const std::array<float, 3> white{1, 1, 1};
    stylerf::io::load_image(p, &white, &alpha);
  });
  return 0;
}
