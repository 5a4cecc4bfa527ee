// A nerfstudio scene whose transforms.json is the input (images/ holds two 2x2 PNGs, frame_0.png and
// frame_1.png): the loader must refuse bad JSON, bad intrinsics, distortion, bad poses and bad paths with
// an Error.
#include <sys/stat.h>

#include "fuzz/fuzz_common.hpp"
#include "lib/io/image.hpp"
#include "lib/scene/scene.hpp"

namespace {
std::string scene_dir() {
  static const std::string dir = [] {
    const std::string d = fuzz::scratch("nerfstudio");
    ::mkdir(d.c_str(), 0700);
    ::mkdir((d + "/images").c_str(), 0700);
    stylerf::io::Image img;
    img.width = img.height = 2;
    img.data.assign(12, 0.5f);
    for (const char* name : {"/images/frame_0.png", "/images/frame_1.png"}) stylerf::io::save_png(d + name, img);
    return d;
  }();
  return dir;
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string dir = scene_dir();
  std::ofstream(dir + "/transforms.json", std::ios::binary | std::ios::trunc)
      .write(reinterpret_cast<const char*>(data), std::streamsize(size));
  stylerf::scene::LoadOptions lo;
  lo.load_images = false;
  fuzz::expect_clean([&] { stylerf::scene::load_scene(dir, lo); });
  return 0;
}
