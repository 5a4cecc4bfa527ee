// COLMAP (binary and text) and nerfstudio scenes: a generated capture with known poses is written in each
// format and as a Blender-format copy; every copy must give the same rays (1e-6). Then every bad input the
// readers promise a clear error for, each naming the file.
#include <doctest/doctest.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <functional>
#include <iomanip>
#include <nlohmann/json.hpp>
#include <sstream>

#include "host/error.hpp"
#include "host/files.hpp"
#include "lib/io/image.hpp"
#include "lib/scene/colmap_model.hpp"
#include "lib/scene/poses.hpp"
#include "lib/scene/rays.hpp"
#include "lib/scene/scene.hpp"
#include "tests/testing.hpp"

using namespace stylerf;
using namespace stylerf::scene;
using testing::error_of;
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

struct TempDir : testing::TempDir {
  explicit TempDir(const std::string& tag) : testing::TempDir("colmap", tag) {}
};

bool has(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

// A capture with known cameras: poses (OpenGL camera-to-world), pinhole intrinsics, a camera id per view,
// and 3D points every camera sees (for COLMAP's depth bounds).
struct Truth {
  struct V {
    Pose c2w;
    uint32_t camera = 1;
    std::string name;
  };
  std::vector<V> views;
  std::map<uint32_t, std::array<double, 4>> intr;  // fx, fy, cx, cy
  int width = 24, height = 18;
  std::vector<Vec3> points;
};

// 360: 22 cameras at distance 1 from the origin (11 azimuths symmetric about +x, elevations +-20 degrees)
// looking at it with +z up: already in the frame the object-centric normalisation produces (focus at the
// origin, mean up +z, mean position along +x, mean distance 1), so the loaders' poses equal these.
Truth object_capture(bool two_cameras) {
  Truth t;
  const double deg = std::acos(-1.0) / 180.0;
  int k = 0;
  for (double az : {0.0, 30.0, -30.0, 60.0, -60.0, 90.0, -90.0, 120.0, -120.0, 150.0, -150.0})
    for (double el : {20.0, -20.0}) {
      const Vec3 eye{std::cos(el * deg) * std::cos(az * deg), std::cos(el * deg) * std::sin(az * deg), std::sin(el * deg)};
      Truth::V v;
      v.c2w = look_at(eye, {0, 0, 0}, {0, 0, 1});
      v.camera = two_cameras && k % 3 == 1 ? 2 : 1;
      char name[32];
      std::snprintf(name, sizeof name, "view%03d.png", k++);
      v.name = name;
      t.views.push_back(v);
    }
  t.intr[1] = {30.0, 28.0, 12.0, 9.0};
  if (two_cameras) t.intr[2] = {26.0, 27.0, 11.25, 9.5};
  for (int i = 0; i < 27; ++i) t.points.push_back({0.1 * (i % 3 - 1), 0.1 * (i / 3 % 3 - 1), 0.1 * (i / 9 - 1)});
  return t;
}

// Forward-facing: 20 cameras looking down -z within +-6 degrees of yaw, content at depths 2..8.
Truth forward_capture() {
  Truth t;
  for (int i = 0; i < 20; ++i) {
    const double yaw = (i - 9.5) * 0.6 * std::acos(-1.0) / 180.0;
    Truth::V v;
    const Vec3 pos{0.1 * (i % 5) - 0.2, 0.1 * (i / 5) - 0.15, 0.0};
    v.c2w = look_at(pos, add(pos, {-std::sin(yaw), 0, -std::cos(yaw)}), {0, 1, 0});
    char name[32];
    std::snprintf(name, sizeof name, "img%03d.png", i);
    v.name = name;
    t.views.push_back(v);
  }
  t.intr[1] = {30.0, 30.0, 12.0, 9.0};
  for (int i = 0; i < 40; ++i) t.points.push_back({0.2 * (i % 5 - 2), 0.2 * (i / 5 % 4 - 2), -2.0 - 6.0 * (i / 20)});
  return t;
}

void write_images(const Truth& t, const fs::path& dir) {
  fs::create_directories(dir);
  for (size_t i = 0; i < t.views.size(); ++i) {
    io::Image img;
    img.width = t.width, img.height = t.height;
    img.data.resize(size_t(3) * t.width * t.height);
    for (size_t k = 0; k < img.data.size(); ++k) img.data[k] = float((k * 7 + i * 13) % 251) / 250.0f;
    io::save_png((dir / t.views[i].name).string(), img);
  }
}

ColmapModel to_colmap(const Truth& t) {
  ColmapModel m;
  for (const auto& [id, in] : t.intr) {
    ColmapCamera c;
    c.id = id;
    c.model_id = colmap_model_id("PINHOLE");
    c.width = uint64_t(t.width), c.height = uint64_t(t.height);
    c.params = {in[0], in[1], in[2], in[3]};
    m.cameras[id] = c;
  }
  for (size_t i = 0; i < t.views.size(); ++i) {
    ColmapImage im;
    im.id = uint32_t(i + 1);
    c2w_to_colmap(t.views[i].c2w, im.qvec, im.tvec);
    im.camera_id = t.views[i].camera;
    im.name = t.views[i].name;
    for (size_t p = 0; p < t.points.size(); ++p) {
      im.xys.push_back({1.0 + p, 2.0});
      im.point3d_ids.push_back(int64_t(p + 1));
    }
    im.xys.push_back({0.5, 0.5});
    im.point3d_ids.push_back(-1);  // an unmatched feature
    m.images.push_back(im);
  }
  for (size_t p = 0; p < t.points.size(); ++p) {
    ColmapPoint pt;
    pt.id = p + 1;
    pt.xyz = t.points[p];
    for (size_t i = 0; i < t.views.size(); ++i) pt.track.push_back({uint32_t(i + 1), uint32_t(p)});
    m.points.push_back(pt);
  }
  return m;
}

void write_colmap(const Truth& t, const fs::path& dir, bool binary) {
  write_images(t, dir / "images");
  write_colmap_model(to_colmap(t), (dir / "sparse" / "0").string(), binary);
}

json matrix(const Pose& p) {
  json m = json::array();
  for (int r = 0; r < 3; ++r) m.push_back({p.m[r][0], p.m[r][1], p.m[r][2], p.m[r][3]});
  m.push_back({0, 0, 0, 1});
  return m;
}

json nerfstudio_json(const Truth& t) {
  json j;
  const bool shared = t.intr.size() == 1;
  auto put_intr = [&](json& o, uint32_t cam) {
    const auto& in = t.intr.at(cam);
    o["fl_x"] = in[0], o["fl_y"] = in[1], o["cx"] = in[2], o["cy"] = in[3], o["w"] = t.width, o["h"] = t.height;
    o["k1"] = 0.0, o["k2"] = 0.0, o["p1"] = 0.0, o["p2"] = 0.0;
  };
  j["camera_model"] = "OPENCV";
  if (shared) put_intr(j, 1);
  j["applied_transform"] = {{1, 0, 0, 0}, {0, 0, 1, 0}, {0, -1, 0, 0}};
  j["frames"] = json::array();
  for (const auto& v : t.views) {
    json f;
    f["file_path"] = "images/" + v.name;
    f["transform_matrix"] = matrix(v.c2w);
    if (!shared) put_intr(f, v.camera);
    j["frames"].push_back(f);
  }
  return j;
}

void write_nerfstudio(const Truth& t, const fs::path& dir) {
  write_images(t, dir / "images");
  host::write_file_atomic((dir / "transforms.json").string(), nerfstudio_json(t).dump(1));
}

// Blender copy (one camera, centred principal point): the same split as the COLMAP loader (every 8th
// view in name order is a test view).
void write_blender(const Truth& t, const fs::path& dir) {
  write_images(t, dir / "images");
  const auto& in = t.intr.at(1);
  for (const char* split : {"train", "test"}) {
    json j;
    j["camera_angle_x"] = 2 * std::atan(0.5 * t.width / in[0]);
    j["camera_angle_y"] = 2 * std::atan(0.5 * t.height / in[1]);
    j["frames"] = json::array();
    for (size_t i = 0; i < t.views.size(); ++i) {
      if ((i % 8 == 0) != (std::string(split) == "test")) continue;
      const std::string stem = fs::path(t.views[i].name).stem().string();
      j["frames"].push_back({{"file_path", "./images/" + stem}, {"transform_matrix", matrix(t.views[i].c2w)}});
    }
    host::write_file_atomic((dir / ("transforms_" + std::string(split) + ".json")).string(), j.dump(1));
  }
}

LoadOptions cameras_only() {
  LoadOptions o;
  o.load_images = false;
  return o;
}

double max_ray_difference(const Scene& a, const Camera& ca, const Scene& b, const Camera& cb) {
  const Rays ra = camera_rays(a, ca), rb = camera_rays(b, cb);
  REQUIRE(ra.size() == rb.size());
  double worst = 0;
  for (size_t k = 0; k < ra.origins.size(); ++k) {
    worst = testing::max_or_nan(worst, double(std::fabs(ra.origins[k] - rb.origins[k])));
    worst = testing::max_or_nan(worst, double(std::fabs(ra.directions[k] - rb.directions[k])));
  }
  return worst;
}

// Every view of `s` against the same-named view of `ref`.
void check_same_rays(const Scene& s, const Scene& ref) {
  REQUIRE(s.train.size() == ref.train.size());
  REQUIRE(s.test.size() == ref.test.size());
  for (auto [sv, rv] : {std::make_pair(&s.train, &ref.train), std::make_pair(&s.test, &ref.test)})
    for (size_t i = 0; i < sv->size(); ++i) {
      INFO(s.format << " view " << (*sv)[i].image_path);
      CHECK(fs::path((*sv)[i].image_path).stem() == fs::path((*rv)[i].image_path).stem());
      CHECK(max_ray_difference(s, (*sv)[i].camera, ref, (*rv)[i].camera) < 1e-6);
    }
}

// The truth camera of each loaded view (same name), for layouts the normalisation leaves unchanged.
void check_against_truth(const Scene& s, const Truth& t) {
  int seen = 0;
  for (const auto* views : {&s.train, &s.test})
    for (const View& v : *views) {
      const std::string name = fs::path(v.image_path).filename().string();
      for (const auto& tv : t.views) {
        if (tv.name != name) continue;
        Camera c;
        for (int r = 0; r < 3; ++r)
          for (int k = 0; k < 4; ++k) c.c2w[r][k] = float(tv.c2w.m[r][k]);
        const auto& in = t.intr.at(tv.camera);
        c.fx = float(in[0]), c.fy = float(in[1]), c.cx = float(in[2]), c.cy = float(in[3]);
        c.width = t.width, c.height = t.height;
        INFO(s.format << " " << name);
        CHECK(max_ray_difference(s, v.camera, s, c) < 1e-6);
        ++seen;
      }
    }
  CHECK(seen == int(t.views.size()));
}

}  // namespace

TEST_CASE("COLMAP text and binary, nerfstudio and Blender copies of a 360 capture give the same rays") {
  TempDir tmp("roundtrip");
  const Truth t = object_capture(false);
  write_colmap(t, tmp.path / "text", false);
  write_colmap(t, tmp.path / "bin", true);
  write_nerfstudio(t, tmp.path / "ns");
  write_blender(t, tmp.path / "blender");
  const Scene ref = load_scene((tmp.path / "blender").string(), cameras_only());
  for (const char* copy : {"text", "bin", "ns"}) {
    INFO(copy);
    const Scene s = load_scene((tmp.path / copy).string(), cameras_only());
    CHECK(s.format == (std::string(copy) == "ns" ? "nerfstudio-object" : "colmap-object"));
    CHECK_FALSE(s.effects.ndc);
    CHECK(s.train.size() == 19);
    CHECK(s.test.size() == 3);
    check_same_rays(s, ref);
    check_against_truth(s, t);
    CHECK(has(s.describe(), "object-centric capture"));
    CHECK(s.aabb[1][0] > 0.1f);
    CHECK(s.aabb[1][0] < 0.9f);
    CHECK(s.near > 0.0f);
    CHECK(s.far > 1.0f);
  }
  // With images: the pixels arrive too, one size.
  LoadOptions with_images;
  const Scene s = load_scene((tmp.path / "bin").string(), with_images);
  CHECK(s.train[0].rgb.size() == size_t(24 * 18 * 3));
  // COLMAP's bounds: the points lie within 0.1*sqrt(3) of the origin, cameras at distance 1.
  const Scene txt = load_scene((tmp.path / "text").string(), cameras_only());
  CHECK(txt.depth_near == doctest::Approx(1 - 0.1 * std::sqrt(3.0)).epsilon(0.05));
  CHECK(txt.depth_far == doctest::Approx(1 + 0.1 * std::sqrt(3.0)).epsilon(0.05));
}

TEST_CASE("COLMAP and nerfstudio: several cameras, intrinsics per image") {
  TempDir tmp("cameras");
  const Truth t = object_capture(true);
  write_colmap(t, tmp.path / "text", false);
  write_colmap(t, tmp.path / "bin", true);
  write_nerfstudio(t, tmp.path / "ns");
  for (const char* copy : {"text", "bin", "ns"}) {
    INFO(copy);
    const Scene s = load_scene((tmp.path / copy).string(), cameras_only());
    check_against_truth(s, t);
  }
  const ColmapModel m = read_colmap_model((tmp.path / "bin" / "sparse" / "0").string());
  CHECK(m.cameras.size() == 2);
  CHECK(m.images.size() == 22);
  CHECK(m.points.size() == 27);
  CHECK(m.images[1].camera_id == 2);
}

TEST_CASE("COLMAP and nerfstudio: a forward-facing capture loads as NDC, with the reason noted") {
  TempDir tmp("forward");
  const Truth t = forward_capture();
  write_colmap(t, tmp.path / "text", false);
  write_nerfstudio(t, tmp.path / "ns");
  for (const char* copy : {"text", "ns"}) {
    INFO(copy);
    const Scene s = load_scene((tmp.path / copy).string(), cameras_only());
    CHECK(s.effects.ndc);
    CHECK(s.format == (std::string(copy) == "ns" ? "nerfstudio-forward" : "colmap-forward"));
    CHECK(has(s.describe(), "forward-facing capture"));
    CHECK(s.near == 0.0f);
    CHECK(s.far == 1.0f);
    CHECK(s.depth_near == doctest::Approx(1 / 0.75));  // LLFF's scaling of the nearest bound
    CHECK(s.train.size() == 17);
  }
  LoadOptions off = cameras_only();
  off.ndc = Switch::off;
  const Scene s = load_scene((tmp.path / "text").string(), off);
  CHECK_FALSE(s.effects.ndc);
  CHECK(has(s.describe(), "NDC forced off"));
  // Bounds from the points: depths 2 and 8 along -z (the cameras yaw a little): far/near about 4.
  CHECK(s.depth_far / s.depth_near == doctest::Approx(4.0).epsilon(0.05));
}

TEST_CASE("COLMAP reader: quaternion conversion round trip, camera models and their parameters") {
  const Pose p = look_at({0.3, -2.0, 0.7}, {0.1, 0.2, -0.1}, {0, 0, 1});
  std::array<double, 4> q;
  std::array<double, 3> tv;
  c2w_to_colmap(p, q, tv);
  const Pose back = colmap_c2w(q, tv, "test");
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) CHECK(back.m[r][c] == doctest::Approx(p.m[r][c]).epsilon(1e-12));
  // OpenCV camera z is forward: a point straight ahead has positive camera z.
  const Vec3 ahead = add(p.axis(3), scale(p.axis(2), -2.0));
  // x_cam = R x + t, R from q: check z component via the c2w relation.
  const double depth = -dot(sub(ahead, back.axis(3)), back.axis(2));
  CHECK(depth == doctest::Approx(2.0));
  CHECK(colmap_param_count(colmap_model_id("SIMPLE_PINHOLE")) == 3);
  CHECK(colmap_param_count(colmap_model_id("OPENCV")) == 8);
  ColmapCamera c;
  c.model_id = colmap_model_id("SIMPLE_RADIAL");
  c.params = {100, 50, 40, 0.0};
  CHECK(c.fx() == 100);
  CHECK(c.fy() == 100);
  CHECK(c.cx() == 50);
  CHECK(c.cy() == 40);
  CHECK(c.is_pinhole());
  c.params[3] = 0.01;
  CHECK_FALSE(c.is_pinhole());
  c.model_id = colmap_model_id("OPENCV_FISHEYE");
  c.params = {100, 100, 50, 40, 0, 0, 0, 0};
  CHECK_FALSE(c.is_pinhole());
}

TEST_CASE("bad COLMAP inputs give errors naming the file") {
  TempDir tmp("bad");
  const Truth t = object_capture(false);
  write_colmap(t, tmp.path / "src_bin", true);
  write_colmap(t, tmp.path / "src_txt", false);
  auto fresh = [&](const std::string& name, bool binary) {
    const fs::path p = tmp.path / name;
    fs::copy(tmp.path / (binary ? "src_bin" : "src_txt"), p, fs::copy_options::recursive);
    return p;
  };
  auto load_error = [&](const fs::path& p) { return error_of([&] { load_scene(p.string(), cameras_only()); }); };
  auto file = [](const fs::path& p, const std::string& f) { return (p / "sparse" / "0" / f).string(); };
  {
    const fs::path p = fresh("truncated_cameras", true);
    const std::string b = host::read_file(file(p, "cameras.bin"));
    host::write_file_atomic(file(p, "cameras.bin"), b.substr(0, b.size() - 5));
    const std::string e = load_error(p);
    CHECK(has(e, file(p, "cameras.bin")));
    CHECK(has(e, "truncated"));
  }
  {
    const fs::path p = fresh("truncated_images", true);
    const std::string b = host::read_file(file(p, "images.bin"));
    host::write_file_atomic(file(p, "images.bin"), b.substr(0, b.size() / 2));
    const std::string e = load_error(p);
    CHECK(has(e, file(p, "images.bin")));
    CHECK(has(e, "truncated"));
  }
  {
    // A count larger than the file can hold: refused before anything is allocated.
    const fs::path p = fresh("count", true);
    std::string b = host::read_file(file(p, "points3D.bin"));
    const uint64_t huge = 1ull << 40;
    std::memcpy(&b[0], &huge, 8);
    host::write_file_atomic(file(p, "points3D.bin"), b);
    const std::string e = load_error(p);
    CHECK(has(e, file(p, "points3D.bin")));
    CHECK(has(e, "says it holds 1099511627776 3D points"));
  }
  {
    const fs::path p = fresh("extra", true);
    host::write_file_atomic(file(p, "cameras.bin"), host::read_file(file(p, "cameras.bin")) + std::string(16, '\0'));
    const std::string e = load_error(p);
    CHECK(has(e, file(p, "cameras.bin")));
    CHECK(has(e, "left over"));
  }
  {
    const fs::path p = fresh("model_id", true);
    std::string b = host::read_file(file(p, "cameras.bin"));
    const int32_t bad = 99;
    std::memcpy(&b[8 + 4], &bad, 4);
    host::write_file_atomic(file(p, "cameras.bin"), b);
    const std::string e = load_error(p);
    CHECK(has(e, file(p, "cameras.bin")));
    CHECK(has(e, "unknown camera model id 99"));
  }
  {
    const fs::path p = fresh("model_name", false);
    host::write_file_atomic(file(p, "cameras.txt"), "1 FANCY_LENS 24 18 30 30 12 9\n");
    const std::string e = load_error(p);
    CHECK(has(e, file(p, "cameras.txt") + " line 1"));
    CHECK(has(e, "unknown camera model 'FANCY_LENS'"));
  }
  {
    const fs::path p = fresh("params", false);
    host::write_file_atomic(file(p, "cameras.txt"), "1 PINHOLE 24 18 30 30 12\n");
    const std::string e = load_error(p);
    CHECK(has(e, file(p, "cameras.txt")));
    CHECK(has(e, "takes 4 parameters"));
  }
  {
    const fs::path p = fresh("missing_camera", false);
    std::string s = host::read_file(file(p, "images.txt"));
    const size_t at = s.find(" 1 view005.png");
    REQUIRE(at != std::string::npos);
    s.replace(at, 2, " 7");
    host::write_file_atomic(file(p, "images.txt"), s);
    const std::string e = load_error(p);
    CHECK(has(e, file(p, "images.txt")));
    CHECK(has(e, "refers to camera 7"));
    CHECK(has(e, file(p, "cameras.txt")));
  }
  {
    const fs::path p = fresh("missing_point", true);
    ColmapModel m = read_colmap_model((p / "sparse" / "0").string());
    m.images[3].point3d_ids[0] = 999;
    write_colmap_model(m, (p / "sparse" / "0").string(), true);
    const std::string e = load_error(p);
    CHECK(has(e, file(p, "images.bin")));
    CHECK(has(e, "observes 3D point 999"));
  }
  {
    const fs::path p = fresh("missing_image", true);
    fs::remove(p / "images" / "view004.png");
    const std::string e = load_error(p);
    CHECK(has(e, (p / "images" / "view004.png").string()));
    CHECK(has(e, "is missing"));
  }
  {
    const fs::path p = fresh("no_images", true);
    fs::remove_all(p / "images");
    CHECK(has(load_error(p), (p / "images").string()));
  }
  {
    const fs::path p = fresh("nan_pose", false);
    std::string s = host::read_file(file(p, "images.txt"));
    const size_t line = s.find("\n3 ");
    REQUIRE(line != std::string::npos);
    const size_t qw_end = s.find(' ', line + 3);
    s.replace(line + 3, qw_end - (line + 3), "nan");  // qw of image 3
    host::write_file_atomic(file(p, "images.txt"), s);
    const std::string e = load_error(p);
    CHECK(has(e, file(p, "images.txt")));
    CHECK(has(e, "non-finite rotation"));
  }
  {
    const fs::path p = fresh("zero_quaternion", true);
    ColmapModel m = read_colmap_model((p / "sparse" / "0").string());
    m.images[2].qvec = {0, 0, 0, 0};
    write_colmap_model(m, (p / "sparse" / "0").string(), true);
    const std::string e = load_error(p);
    CHECK(has(e, file(p, "images.bin")));
    CHECK(has(e, "quaternion"));
  }
  {
    // An image file whose size differs from what its camera says.
    const fs::path p = fresh("size", false);
    io::Image img;
    img.width = 30, img.height = 20;
    img.data.assign(size_t(3 * 30 * 20), 0.5f);
    io::save_png((p / "images" / "view006.png").string(), img);
    const std::string e = load_error(p);
    CHECK(has(e, "view006.png is 30x20"));
    CHECK(has(e, file(p, "cameras.txt")));
    CHECK(has(e, "24x18"));
  }
  {
    // Two cameras of different sizes: each image matches its camera, but a scene has one size.
    const fs::path p = fresh("mixed", false);
    ColmapModel m = read_colmap_model((p / "sparse" / "0").string());
    ColmapCamera c2 = m.cameras.at(1);
    c2.id = 2, c2.width = 30, c2.height = 20;
    m.cameras[2] = c2;
    m.images[5].camera_id = 2;
    write_colmap_model(m, (p / "sparse" / "0").string(), false);
    io::Image img;
    img.width = 30, img.height = 20;
    img.data.assign(size_t(3 * 30 * 20), 0.5f);
    io::save_png((p / "images" / m.images[5].name).string(), img);
    const std::string e = load_error(p);
    CHECK(has(e, m.images[5].name + " is 30x20"));
    CHECK(has(e, "one size"));
  }
  {
    const fs::path p = fresh("distorted", true);
    ColmapModel m = read_colmap_model((p / "sparse" / "0").string());
    m.cameras[1].model_id = colmap_model_id("OPENCV");
    m.cameras[1].params = {30, 28, 12, 9, 0.05, -0.01, 0, 0};
    write_colmap_model(m, (p / "sparse" / "0").string(), true);
    const std::string e = load_error(p);
    CHECK(has(e, file(p, "cameras.bin")));
    CHECK(has(e, "OPENCV with distortion"));
    CHECK(has(e, "colmap image_undistorter"));
    // The same model with zero distortion is a pinhole and loads.
    m.cameras[1].params = {30, 28, 12, 9, 0, 0, 0, 0};
    write_colmap_model(m, (p / "sparse" / "0").string(), true);
    CHECK(load_scene(p.string(), cameras_only()).train.size() == 19);
  }
  {
    const fs::path p = fresh("text_garbage", false);
    host::write_file_atomic(file(p, "points3D.txt"), "1 0.5 0.5 zero 1 2 3 0.1\n");
    const std::string e = load_error(p);
    CHECK(has(e, file(p, "points3D.txt") + " line 1"));
    CHECK(has(e, "'zero' is not a number"));
  }
  {
    const fs::path p = fresh("no_points_file", false);
    fs::remove(file(p, "points3D.txt"));
    CHECK(has(load_error(p), "points3D.bin (or points3D.txt) is missing"));
  }
  {
    // The model under sparse/ directly (no 0/) is found too.
    const fs::path p = fresh("flat", true);
    for (const char* f : {"cameras.bin", "images.bin", "points3D.bin"}) fs::rename(file(p, f), p / "sparse" / f);
    fs::remove(p / "sparse" / "0");
    CHECK(load_scene(p.string(), cameras_only()).format == "colmap-object");
  }
}

TEST_CASE("bad nerfstudio inputs give errors naming the file") {
  TempDir tmp("bad_ns");
  const Truth t = object_capture(false);
  write_images(t, tmp.path / "images");
  const std::string path = (tmp.path / "transforms.json").string();
  auto error_with = [&](const std::function<void(json&)>& edit) {
    json j = nerfstudio_json(t);
    edit(j);
    host::write_file_atomic(path, j.dump());
    return error_of([&] { load_scene(tmp.path.string(), cameras_only()); });
  };
  std::string e = error_with([](json& j) { j["k1"] = 0.02; });
  CHECK(has(e, path));
  CHECK(has(e, "distortion (k1 = 0.02)"));
  e = error_with([](json& j) { j["frames"][4]["p2"] = 0.001; });
  CHECK(has(e, path + " frame 4"));
  CHECK(has(e, "p2 = 0.001"));
  e = error_with([](json& j) { j["camera_model"] = "OPENCV_FISHEYE"; });
  CHECK(has(e, path));
  CHECK(has(e, "not a pinhole"));
  e = error_with([](json& j) { j.erase("fl_x"); });
  CHECK(has(e, path + " frame 0: 'fl_x' is missing"));
  e = error_with([](json& j) { j["frames"][3]["transform_matrix"][1][2] = nullptr; });
  CHECK(has(e, path + " frame 3"));
  CHECK(has(e, "not a number"));
  e = error_with([](json& j) {
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) j["frames"][2]["transform_matrix"][r][c] = j["frames"][2]["transform_matrix"][r][c].get<double>() * 2;
  });
  CHECK(has(e, path + " frame 2"));
  CHECK(has(e, "not a rigid transform"));
  e = error_with([](json& j) { j["frames"][7]["file_path"] = "images/nothere.png"; });
  CHECK(has(e, "nothere.png is missing"));
  CHECK(has(e, path));
  e = error_with([](json& j) { j["w"] = 32; });
  CHECK(has(e, "is 24x18"));
  CHECK(has(e, path));
  e = error_with([](json& j) { j["frames"] = json::array(); });
  CHECK(has(e, path + ": 'frames' is missing or empty"));
  e = error_with([](json& j) { j["applied_transform"] = "yes"; });
  CHECK(has(e, path + ": 'applied_transform'"));
  host::write_file_atomic(path, "{\"frames\": [");
  CHECK(has(error_of([&] { load_scene(tmp.path.string(), cameras_only()); }), path + " is not valid JSON"));
  // Blender's transforms_train.json wins over transforms.json: the folder is a Blender scene.
  host::write_file_atomic((tmp.path / "transforms_train.json").string(), "{}");
  CHECK(has(error_of([&] { load_scene(tmp.path.string(), cameras_only()); }), "transforms_train.json"));
}
