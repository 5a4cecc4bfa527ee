// `stylerf import` (lib/scene/colmap_import.hpp): COLMAP run end to end on a generated, textured capture
// with known poses, whose recovered cameras must agree with the truth after a similarity alignment (<= 1
// degree, <= 1% of the cameras' extent); the scene folder it writes loads as it is. Then the refusals, each
// naming what is wrong, and nothing left half-written. The pose comparison itself (pose_alignment.hpp) is
// checked on a known similarity. scripts/setup.sh installs colmap; without it the end-to-end case fails
// (it is not skipped).
#include <doctest/doctest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "host/error.hpp"
#include "lib/io/image.hpp"
#include "lib/io/process.hpp"
#include "lib/scene/colmap_import.hpp"
#include "lib/scene/make_scene.hpp"
#include "lib/scene/pose_alignment.hpp"
#include "lib/scene/scene.hpp"
#include "tests/testing.hpp"

using namespace stylerf;
using namespace stylerf::scene;
namespace fs = std::filesystem;

namespace {

struct TempDir : testing::TempDir {
  explicit TempDir(const std::string& tag) : testing::TempDir("import", tag) {}
};

// A textured capture (make-scene --textured, 256 px): its train images copied into images/.
fs::path textured_capture(const fs::path& root, int views) {
  MakeSceneOptions o;
  o.size = 256;
  o.views = views;
  o.textured = true;
  make_scene((root / "truth").string(), o);
  fs::create_directories(root / "photos");
  for (const auto& e : fs::directory_iterator(root / "truth" / "train"))
    if (e.path().extension() == ".png") fs::copy_file(e.path(), root / "photos" / e.path().filename());
  return root / "photos";
}

std::vector<std::string> lines;
void keep(const std::string& l) { lines.push_back(l); }

}  // namespace

TEST_CASE("the pose comparison recovers a known similarity exactly") {
  TempDir t("similarity");
  MakeSceneOptions o;
  o.size = 16;
  o.views = 12;
  make_scene((t.path / "a").string(), o);
  LoadOptions lo;
  lo.load_images = false;
  const Scene a = load_scene((t.path / "a").string(), lo);
  // b = the same cameras moved by x -> s R x + t (R: 30 degrees about z then 20 about x), one turned by 2 deg.
  Scene b = a;
  const double s = 2.5, c1 = std::cos(M_PI / 6), s1 = std::sin(M_PI / 6), c2 = std::cos(M_PI / 9), s2 = std::sin(M_PI / 9);
  const double Rz[3][3] = {{c1, -s1, 0}, {s1, c1, 0}, {0, 0, 1}}, Rx[3][3] = {{1, 0, 0}, {0, c2, -s2}, {0, s2, c2}};
  double R[3][3] = {};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k) R[i][j] += Rx[i][k] * Rz[k][j];
  const double t3[3] = {0.3, -1.0, 2.0};
  for (auto* views : {&b.train, &b.test})
    for (View& v : *views) {
      float m[3][4];
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) m[r][c] = float(R[r][0] * v.camera.c2w[0][c] + R[r][1] * v.camera.c2w[1][c] + R[r][2] * v.camera.c2w[2][c]);
        m[r][3] = float(s * (R[r][0] * v.camera.c2w[0][3] + R[r][1] * v.camera.c2w[1][3] + R[r][2] * v.camera.c2w[2][3]) + t3[r]);
      }
      std::copy(&m[0][0], &m[0][0] + 12, &v.camera.c2w[0][0]);
    }
  const PoseAgreement exact = compare_poses(b, a);
  CHECK(exact.matched == int(a.train.size()));  // test views share train's stems: train stands for them
  CHECK(exact.similarity.scale == doctest::Approx(s).epsilon(1e-5));
  CHECK(exact.max_rotation_deg() < 1e-3);
  CHECK(exact.max_position() < 1e-5);
  // One camera turned by 2 degrees about its own y axis: its error is ~2 degrees, the median stays ~0.
  View& v = b.train[3];
  const double c = std::cos(M_PI / 90), sn = std::sin(M_PI / 90);
  for (int r = 0; r < 3; ++r) {
    const float x = v.camera.c2w[r][0], z = v.camera.c2w[r][2];
    v.camera.c2w[r][0] = float(c * x - sn * z);
    v.camera.c2w[r][2] = float(sn * x + c * z);
  }
  const PoseAgreement one = compare_poses(b, a);
  CHECK(one.max_rotation_deg() == doctest::Approx(2.0).epsilon(0.1));
  CHECK(one.median_rotation_deg() < 0.3);
  testing::expect_error([&] { fit_similarity({{0, 0, 0}, {1, 1, 1}}, {{0, 0, 0}, {1, 1, 1}}); }, "3 or more");
}

TEST_CASE("import: COLMAP recovers a generated textured capture within 1 degree and 1% of its extent") {
  REQUIRE_MESSAGE(!io::find_program("colmap").empty(), "colmap is not installed (scripts/setup.sh installs it)");
  TempDir t("e2e");
  const fs::path photos = textured_capture(t.path, 16);  // 12 train views
  ImportOptions o;
  o.images = photos.string();
  o.out = (t.path / "scene").string();
  o.camera_model = "PINHOLE";  // the generator's cameras have no distortion
  lines.clear();
  const ImportReport r = import_with_colmap(o, keep);
  MESSAGE("registered " << r.registered << "/" << r.images << ", reprojection " << r.mean_reprojection_error << " px");
  CHECK(r.images == 12);
  CHECK(r.registered * 5 >= r.images * 4);
  CHECK(r.phase_seconds.size() == 4);
  CHECK(!lines.empty());
  for (const char* part : {"images", "sparse/0", "colmap/database.db", "colmap/logs/mapper.log"})
    CHECK_MESSAGE(fs::exists(t.path / "scene" / part), part);
  CHECK(!fs::exists(t.path / ("scene.importing-" + std::to_string(::getpid()))));
  LoadOptions lo;
  const Scene imported = load_scene(o.out, lo);  // with its images: what train-density reads
  CHECK(imported.format == "colmap-object");
  CHECK(imported.width() == 256);
  lo.load_images = false;
  const PoseAgreement p = compare_poses(load_scene((t.path / "truth").string(), lo), imported);
  MESSAGE(p.describe());
  CHECK(p.matched == r.registered);
  CHECK(p.max_rotation_deg() <= 1.0);
  CHECK(p.max_position() <= 0.01);
  // An existing scene is kept unless forced.
  testing::expect_error([&] { import_with_colmap(o, keep); }, "exists (--force");
}

TEST_CASE("import refuses bad photo folders, naming the files, and writes nothing") {
  TempDir t("bad");
  const fs::path photos = textured_capture(t.path, 8);  // 5 train views, 256 px
  ImportOptions o;
  o.images = photos.string();
  o.out = (t.path / "out").string();
  o.colmap = (t.path / "no-colmap-here").string();
  testing::expect_error([&] { import_with_colmap(o, keep); }, "apt-get install colmap");
  o.colmap = "colmap";
  {  // a file that is not an image
    std::ofstream(photos / "notes.txt") << "not a photo";
    testing::expect_error([&] { import_with_colmap(o, keep); }, "notes.txt");
    fs::remove(photos / "notes.txt");
  }
  {  // mixed sizes
    io::Image small;
    small.width = 100;
    small.height = 80;
    small.data.assign(size_t(3) * 100 * 80, 0.5f);
    io::save_png((photos / "odd.png").string(), small);
    const std::string e = testing::error_of([&] { import_with_colmap(o, keep); });
    CHECK(e.find("different sizes") != std::string::npos);
    CHECK(e.find("odd.png") != std::string::npos);
    fs::remove(photos / "odd.png");
  }
  {  // too few
    TempDir few("few");
    int n = 0;
    for (const auto& e : fs::directory_iterator(photos))
      if (n++ < 2) fs::copy_file(e.path(), few.path / e.path().filename());
    ImportOptions f = o;
    f.images = few.path.string();
    testing::expect_error([&] { import_with_colmap(f, keep); }, "needs 3 or more");
  }
  ImportOptions m = o;
  m.matcher = "vocab";
  testing::expect_error([&] { import_with_colmap(m, keep); }, "matcher must be auto, exhaustive or sequential");
  m = o;
  m.camera_model = "FISHEYE_PLUS";
  testing::expect_error([&] { import_with_colmap(m, keep); }, "camera model");
  testing::expect_error([&] {
    ImportOptions d = o;
    d.images = (t.path / "missing").string();
    import_with_colmap(d, keep);
  }, "not a folder");
  CHECK(!fs::exists(t.path / "out"));
}

TEST_CASE("EXIF orientation is read from a JPEG's APP1 segment") {
  TempDir t("exif");
  // A minimal JPEG prefix: SOI, APP1 "Exif" with a little-endian TIFF header, IFD0 of one entry (0x0112 = 6).
  const unsigned char bytes[] = {0xFF, 0xD8, 0xFF, 0xE1, 0x00, 0x22, 'E', 'x', 'i', 'f', 0, 0,
                                 'I', 'I', 0x2A, 0x00, 0x08, 0x00, 0x00, 0x00, 0x01, 0x00,
                                 0x12, 0x01, 0x03, 0x00, 0x01, 0x00, 0x00, 0x00, 0x06, 0x00, 0x00, 0x00,
                                 0x00, 0x00, 0x00, 0x00, 0xFF, 0xD9};
  const fs::path p = t.path / "rotated.jpg";
  std::ofstream(p, std::ios::binary).write(reinterpret_cast<const char*>(bytes), sizeof bytes);
  CHECK(io::exif_orientation(p.string()) == 6);
  const fs::path png = t.path / "plain.png";
  io::Image img;
  img.width = img.height = 4;
  img.data.assign(48, 0.2f);
  io::save_png(png.string(), img);
  CHECK(io::exif_orientation(png.string()) == 0);
}
