// A Blender-format scene whose transforms_train.json is the input (the test split is a fixed valid file
// and the images are 2x2 PNGs): the loader must refuse bad JSON, bad poses, bad paths with an Error.
#include <sys/stat.h>

#include "fuzz/fuzz_common.hpp"
#include "lib/io/image.hpp"
#include "lib/scene/scene.hpp"

namespace {
std::string scene_dir() {
  static const std::string dir = [] {
    const std::string d = fuzz::scratch("scene");
    ::mkdir(d.c_str(), 0700);
    ::mkdir((d + "/train").c_str(), 0700);
    stylerf::io::Image img;
    img.width = img.height = 2;
    img.data.assign(12, 0.5f);
    for (const char* name : {"/train/r_0.png", "/train/r_1.png"}) stylerf::io::save_png(d + name, img);
    std::ofstream(d + "/transforms_test.json")
        << R"({"camera_angle_x": 0.7, "frames": [{"file_path": "./train/r_1", "transform_matrix": )"
        << R"([[1,0,0,0],[0,1,0,0],[0,0,1,4],[0,0,0,1]]}]})";
    return d;
  }();
  return dir;
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string dir = scene_dir();
  std::ofstream(dir + "/transforms_train.json", std::ios::binary | std::ios::trunc)
      .write(reinterpret_cast<const char*>(data), std::streamsize(size));
  stylerf::scene::LoadOptions lo;
  lo.load_images = false;
  fuzz::expect_clean([&] { stylerf::scene::load_scene(dir, lo); });
  return 0;
}
