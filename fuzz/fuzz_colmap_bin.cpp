// COLMAP binary models: the first byte picks the file (0 cameras.bin, 1 images.bin, 2 points3D.bin; modulo
// 3) and the rest is its content. The reader must refuse truncated files, counts larger than the file,
// unknown camera models and non-finite values with an Error, and never allocate by a count it was given.
#include <sys/stat.h>

#include "fuzz/fuzz_common.hpp"
#include "lib/scene/colmap_model.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  static const char* names[3] = {"cameras.bin", "images.bin", "points3D.bin"};
  const int which = data[0] % 3;
  const std::string path = fuzz::write(names[which], data + 1, size - 1);
  fuzz::expect_clean([&] {
    if (which == 0) stylerf::scene::read_colmap_cameras(path);
    if (which == 1) stylerf::scene::read_colmap_images(path);
    if (which == 2) stylerf::scene::read_colmap_points(path);
  });
  return 0;
}
