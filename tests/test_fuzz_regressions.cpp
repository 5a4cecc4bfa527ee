// Replays the fuzz seeds (fuzz/corpus/<harness>/) and every input a fuzz run found
// (tests/data/fuzz_regressions/<harness>/) through the readers the harnesses drive: each must be read
// or refused with a host::Error, never crash or throw anything else. The same files, and cut-down and
// bit-flipped copies of each, so the replay also covers damaged versions of valid files.
#include <doctest/doctest.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <map>

#include "host/error.hpp"
#include "host/files.hpp"
#include "lib/io/checkpoint.hpp"
#include "lib/io/image.hpp"
#include "lib/io/npy.hpp"
#include "lib/io/safetensors.hpp"
#include "lib/scene/colmap_model.hpp"
#include "lib/scene/scene.hpp"
#include "tests/small_scene.hpp"

using namespace stylerf;
namespace fs = std::filesystem;

namespace {
const fs::path kFixtures = STYLERF_TEST_FIXTURES;

std::string scene_with_train_json(const std::string& bytes) {
  const fs::path d = testing::small_work_dir() / "fuzz_scene";
  static bool made = [&] {
    fs::create_directories(d / "train");
    io::Image img;
    img.width = img.height = 2;
    img.data.assign(12, 0.5f);
    for (const char* n : {"r_0.png", "r_1.png"}) io::save_png((d / "train" / n).string(), img);
    host::write_file_atomic((d / "transforms_test.json").string(),
                            R"({"camera_angle_x": 0.7, "frames": [{"file_path": "./train/r_1", )"
                            R"("transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,4],[0,0,0,1]]}]})");
    return true;
  }();
  (void)made;
  host::write_file_atomic((d / "transforms_train.json").string(), bytes);
  return d.string();
}

// fuzz_nerfstudio_json's scene: images/frame_0.png and frame_1.png (2x2), transforms.json the input.
std::string scene_with_transforms_json(const std::string& bytes) {
  const fs::path d = testing::small_work_dir() / "fuzz_nerfstudio";
  static bool made = [&] {
    fs::create_directories(d / "images");
    io::Image img;
    img.width = img.height = 2;
    img.data.assign(12, 0.5f);
    for (const char* n : {"frame_0.png", "frame_1.png"}) io::save_png((d / "images" / n).string(), img);
    return true;
  }();
  (void)made;
  host::write_file_atomic((d / "transforms.json").string(), bytes);
  return d.string();
}

// fuzz_colmap_bin's input: the first byte picks cameras.bin, images.bin or points3D.bin, the rest is the file.
void read_colmap_bin(const std::string& p) {
  const std::string bytes = host::read_file(p);
  if (bytes.empty()) return;
  static const char* names[3] = {"cameras.bin", "images.bin", "points3D.bin"};
  const int which = (unsigned char)bytes[0] % 3;
  const fs::path file = testing::small_work_dir() / "fuzz_colmap" / names[which];
  fs::create_directories(file.parent_path());
  host::write_file_atomic(file.string(), bytes.substr(1));
  if (which == 0) scene::read_colmap_cameras(file.string());
  if (which == 1) scene::read_colmap_images(file.string());
  if (which == 2) scene::read_colmap_points(file.string());
}

const std::map<std::string, std::function<void(const std::string&)>>& readers() {
  static const std::map<std::string, std::function<void(const std::string&)>> r = {
      {"npy", [](const std::string& p) { io::read_npy(p); }},
      {"safetensors",
       [](const std::string& p) {
         const auto st = io::SafeTensors::load(p);
         for (const auto& n : st.names()) st.get(n);
       }},
      {"checkpoint", [](const std::string& p) { io::load_checkpoint(p, ""); }},
      {"image", [](const std::string& p) { io::load_image(p); }},
      {"scene_json",
       [](const std::string& p) {
         scene::LoadOptions lo;
         lo.load_images = false;
         scene::load_scene(scene_with_train_json(host::read_file(p)), lo);
       }},
      {"colmap_bin", read_colmap_bin},
      {"nerfstudio_json",
       [](const std::string& p) {
         scene::LoadOptions lo;
         lo.load_images = false;
         scene::load_scene(scene_with_transforms_json(host::read_file(p)), lo);
       }},
  };
  return r;
}

// Read or refused with an Error; anything else fails the test, naming the input.
void replay(const std::string& harness, const std::string& path, const std::string& label) {
  INFO(harness << ": " << label);
  try {
    readers().at(harness)(path);
  } catch (const host::Error&) {
  } catch (const std::exception& e) {
    FAIL_CHECK("escaped as " << typeid(e).name() << ": " << e.what());
  }
}
}  // namespace

TEST_CASE("fuzz seeds, damaged copies and past findings are read or refused cleanly") {
  int files = 0;
  const fs::path scratch = testing::small_work_dir() / "fuzz_replay";
  fs::create_directories(scratch);
  for (const fs::path& base : {kFixtures / ".." / ".." / "fuzz" / "corpus", kFixtures / "fuzz_regressions"}) {
    for (const auto& [harness, reader] : readers()) {
      const fs::path dir = base / harness;
      if (!fs::is_directory(dir)) continue;
      for (const auto& e : fs::directory_iterator(dir)) {
        if (!e.is_regular_file()) continue;
        ++files;
        replay(harness, e.path().string(), e.path().string());
        // Damaged copies: cut at several lengths, and one byte flipped at several places.
        const std::string bytes = host::read_file(e.path().string());
        const std::string copy = (scratch / (harness + e.path().extension().string())).string();
        for (size_t cut : {size_t(0), size_t(1), size_t(8), bytes.size() / 2, bytes.size() - 1}) {
          if (cut > bytes.size()) continue;
          std::ofstream(copy, std::ios::binary | std::ios::trunc) << bytes.substr(0, cut);
          replay(harness, copy, e.path().string() + " cut to " + std::to_string(cut));
        }
        for (size_t at = 0; at < bytes.size(); at += std::max<size_t>(1, bytes.size() / 24)) {
          std::string flipped = bytes;
          flipped[at] = char(flipped[at] ^ 0x5a);
          std::ofstream(copy, std::ios::binary | std::ios::trunc) << flipped;
          replay(harness, copy, e.path().string() + " byte " + std::to_string(at) + " flipped");
        }
      }
    }
  }
  MESSAGE(files << " files replayed");
  CHECK(files >= 12);  // the seeds are there
}
