// Scenes, cameras and rays: the generated scene (exact geometry), the real Blender/LLFF loaders, NDC,
// camera paths, the .npy reader, and every bad input the loaders promise a clear error for.
#include <doctest/doctest.h>
#include <stb/stb_image_write.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>

#include "host/error.hpp"
#include "host/files.hpp"
#include "lib/io/exr.hpp"
#include "lib/io/image.hpp"
#include "lib/io/npy.hpp"
#include "lib/scene/analytic_scene.hpp"
#include "lib/scene/camera_path.hpp"
#include "lib/scene/make_scene.hpp"
#include "lib/scene/masked_background.hpp"
#include "lib/scene/rays.hpp"
#include "lib/scene/scene.hpp"
#include "tests/testing.hpp"

using namespace stylerf;
using testing::error_of;
using namespace stylerf::scene;
namespace fs = std::filesystem;

namespace {

struct TempDir : testing::TempDir {
  explicit TempDir(const std::string& tag) : testing::TempDir("scene", tag) {}
};

bool has(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

// ../shared/data (STYLERF_TEST_DATA, which CTest sets), or "" where it is absent: the real-scene cases (test
// suite "shared", their own CTest entry) then report themselves skipped and return.
std::string data_dir() { return testing::shared_data_dir(); }

#define REAL_DATA_OR_RETURN(root, what)                                                                     \
  if ((root).empty()) {                                                                                      \
    testing::report_skipped("../shared/data is absent (STYLERF_TEST_DATA unset or missing): " what);       \
    return;                                                                                                  \
  }

// A forward-facing LLFF capture written from scratch: 20 cameras looking down -z within +-6 degrees of
// yaw, hwf 240 x 320 with focal 300, bounds [2, 8], and 40 x 30 images in images_8 (image000.png ...).
// The bad-input cases edit copies of it; the real fern has the same layout.
struct LlffFixture {
  std::vector<float> poses;  // [20, 17]
};

LlffFixture write_llff_images(const fs::path& dir) {
  fs::create_directories(dir / "images_8");
  LlffFixture f;
  for (int i = 0; i < 20; ++i) {
    const double yaw = (i - 9.5) * 0.6 * std::acos(-1.0) / 180.0, c = std::cos(yaw), s = std::sin(yaw);
    const double down[3] = {0, -1, 0}, right[3] = {c, 0, -s}, back[3] = {s, 0, c};
    const double pos[3] = {0.1 * (i % 5) - 0.2, 0.1 * (i / 5) - 0.15, 0.0}, hwf[3] = {240, 320, 300};
    for (int r = 0; r < 3; ++r)
      for (double v : {down[r], right[r], back[r], pos[r], hwf[r]}) f.poses.push_back(float(v));
    f.poses.push_back(2.0f);
    f.poses.push_back(8.0f);
    std::vector<unsigned char> px(40 * 30 * 3);
    for (size_t k = 0; k < px.size(); ++k) px[k] = (unsigned char)((k * 7 + size_t(i) * 13) % 251);
    char name[32];
    std::snprintf(name, sizeof name, "image%03d.png", i);
    REQUIRE(stbi_write_png((dir / "images_8" / name).string().c_str(), 40, 30, 3, px.data(), 40 * 3));
  }
  return f;
}

LoadOptions quiet(int downsample = 1) {
  LoadOptions o;
  o.downsample = downsample;
  o.log = nullptr;
  return o;
}

// Generated once per process: 32x32, 10 views -> 8 train, 1 val, 1 test.
const std::string& generated_scene() {
  static TempDir dir("generated");
  static bool made = false;
  if (!made) {
    MakeSceneOptions o;
    o.size = 32;
    o.views = 10;
    make_scene(dir.str("scene"), o);
    made = true;
  }
  static std::string p = dir.str("scene");
  return p;
}

// Independent of the tracer: distance from p to the surface of an analytic shape.
double surface_distance(const Shape& s, const Float3& p) {
  auto len = [](double x, double y, double z) { return std::sqrt(x * x + y * y + z * z); };
  switch (s.kind) {
    case Shape::Kind::sphere:
      return std::fabs(len(p[0] - s.p[0], p[1] - s.p[1], p[2] - s.p[2]) - s.radius);
    case Shape::Kind::box: {
      double out = 0, in = -1e30;
      double o2 = 0;
      for (int a = 0; a < 3; ++a) {
        double c = 0.5 * (s.p[a] + s.q[a]), h = 0.5 * (s.q[a] - s.p[a]);
        double d = std::fabs(p[a] - c) - h;
        in = std::max(in, d);
        if (d > 0) o2 += d * d;
      }
      out = std::sqrt(o2);
      return in > 0 ? out : std::fabs(in);
    }
    case Shape::Kind::cylinder: {
      double r = std::hypot(p[0] - s.p[0], p[1] - s.p[1]) - s.radius;
      double z = std::max(s.p[2] - p[2], p[2] - (s.p[2] + s.height));
      if (r <= 0 && z <= 0) return std::fabs(std::max(r, z));
      return std::hypot(std::max(r, 0.0), std::max(z, 0.0));
    }
    case Shape::Kind::disc:
      return std::fabs(p[2] - s.p[2]);
  }
  return 1e30;
}

}  // namespace

// ------------------------------------------------------------------------------------------------
TEST_CASE("npy: float32 round trip, float64 header parsing, and clear errors") {
  TempDir t("npy");
  std::vector<float> v = {1.5f, -2.0f, 3.25f, 0.0f, 1e-7f, 6e6f};
  io::write_npy_f32(t.str("a.npy"), {2, 3}, v);
  io::NpyArray a = io::read_npy(t.str("a.npy"));
  CHECK(a.dtype == "<f4");
  REQUIRE(a.shape == std::vector<size_t>{2, 3});
  for (size_t i = 0; i < v.size(); ++i) CHECK(a.data[i] == double(v[i]));
  CHECK(has(error_of([&] { io::read_npy_checked(t.str("a.npy"), {-1, 17}, "poses_bounds"); }), "expected (N, 17)"));

  // A float64 file written byte by byte as numpy does (version 1.0).
  auto raw = [&](const std::string& header, const std::string& payload) {
    std::string h = header;
    h.append((64 - (10 + h.size() + 1) % 64) % 64, ' ');
    h += '\n';
    std::string out = std::string("\x93NUMPY\x01\x00", 8) + char(h.size() & 0xff) + char(h.size() >> 8) + h + payload;
    return out;
  };
  double d[2] = {0.5, -7.25};
  std::string payload(reinterpret_cast<const char*>(d), sizeof d);
  host::write_file_atomic(t.str("b.npy"), raw("{'descr': '<f8', 'fortran_order': False, 'shape': (2,), }", payload));
  io::NpyArray b = io::read_npy(t.str("b.npy"));
  CHECK(b.shape == std::vector<size_t>{2});
  CHECK(b.data[1] == -7.25);

  host::write_file_atomic(t.str("trunc.npy"), raw("{'descr': '<f8', 'fortran_order': False, 'shape': (3,), }", payload));
  CHECK(has(error_of([&] { io::read_npy(t.str("trunc.npy")); }), "trunc.npy"));
  CHECK(has(error_of([&] { io::read_npy(t.str("trunc.npy")); }), "truncated"));
  host::write_file_atomic(t.str("big.npy"), raw("{'descr': '>f8', 'fortran_order': False, 'shape': (2,), }", payload));
  CHECK(has(error_of([&] { io::read_npy(t.str("big.npy")); }), "'>f8' is not supported"));
  host::write_file_atomic(t.str("fort.npy"), raw("{'descr': '<f8', 'fortran_order': True, 'shape': (2,), }", payload));
  CHECK(has(error_of([&] { io::read_npy(t.str("fort.npy")); }), "Fortran"));
  host::write_file_atomic(t.str("bad.npy"), "not numpy at all");
  CHECK(has(error_of([&] { io::read_npy(t.str("bad.npy")); }), "bad magic"));
  CHECK(has(error_of([&] { io::read_npy(t.str("missing.npy")); }), "missing.npy does not exist"));
}

// ------------------------------------------------------------------------------------------------
TEST_CASE("make-scene: Blender loader reads it back; pixel rays hit the known surface at the stored depth") {
  const std::string dir = generated_scene();
  Scene s = load_scene(dir, quiet());
  CHECK(s.format == "blender");
  CHECK(s.train.size() == 8);
  CHECK(s.test.size() == 1);
  CHECK(s.width() == 32);
  CHECK(s.height() == 32);
  const Camera& c = s.train[0].camera;
  CHECK(c.fx == doctest::Approx(16.0 / std::tan(0.45)).epsilon(1e-5));
  CHECK(c.fy == doctest::Approx(c.fx));
  CHECK(c.cx == 16.0f);
  CHECK(c.cy == 16.0f);
  CHECK(s.effects.background);
  CHECK_FALSE(s.effects.ndc);
  CHECK_FALSE(s.effects.view_dependence);
  CHECK(s.near == doctest::Approx(1.4f));
  CHECK(s.far == doctest::Approx(6.6f));
  for (const View& v : s.train) {
    CHECK(std::fabs(std::hypot(v.camera.c2w[0][3], v.camera.c2w[1][3], v.camera.c2w[2][3]) - 4.0) < 1e-5);
    REQUIRE(v.alpha.size() == 32u * 32u);
  }
  // Corner pixel: background, alpha 0, composited to white.
  const View& v0 = s.train[0];
  CHECK(v0.alpha[0] == 0.0f);
  CHECK(v0.rgb[0] == 1.0f);

  // Every covered pixel of every view: the pixel-centre ray of the loaded camera, followed for the stored
  // depth, lands on the surface of one of the analytic shapes (checked with distance functions, not the tracer).
  const AnalyticScene truth = AnalyticScene::objects();
  int covered = 0;
  for (const auto* split : {&s.train, &s.test}) {
    for (const View& v : *split) {
      std::string depth_path = v.image_path.substr(0, v.image_path.size() - 4) + "_depth.exr";
      io::ExrImage depth = io::read_exr(depth_path);
      REQUIRE(depth.width == 32);
      REQUIRE(depth.channels == 1);
      Rays r = camera_rays(s, v.camera);
      for (size_t i = 0; i < r.size(); ++i) {
        const float dep = depth.data[i];
        if (v.alpha[i] == 0.0f) {
          CHECK(dep == 0.0f);  // background: no depth
          continue;
        }
        if (dep == 0.0f) continue;  // partly covered edge pixel whose centre misses
        ++covered;
        Float3 p;
        for (int k = 0; k < 3; ++k) p[k] = r.origins[3 * i + k] + dep * r.directions[3 * i + k];
        double best = 1e30;
        for (const Shape& sh : truth.shapes) best = std::min(best, surface_distance(sh, p));
        CHECK(best < 1e-4);  // float32 ray arithmetic at distance ~4
        for (int k = 0; k < 3; ++k) CHECK(std::fabs(p[k]) <= 1.5f);  // inside the scene box
      }
    }
  }
  CHECK(covered > 9 * 32 * 32 / 10);  // the shapes fill a good share of the frames

  // The nearest point of the big sphere, projected into each view: the ray through that pixel position
  // passes through it at depth |camera - centre| - r (unless another shape occludes it, which can only
  // make the stored depth smaller).
  const Shape& ball = truth.shapes[0];
  int unoccluded = 0;
  for (const View& v : s.train) {
    const auto cam = v.camera.position();
    Float3 to{cam[0] - ball.p[0], cam[1] - ball.p[1], cam[2] - ball.p[2]};
    const float dist = std::sqrt(to[0] * to[0] + to[1] * to[1] + to[2] * to[2]);
    Float3 q;
    for (int k = 0; k < 3; ++k) q[k] = ball.p[k] + ball.radius * to[k] / dist;
    float px, py;
    REQUIRE(v.camera.project(q, px, py));
    float o[3], d[3];
    pixel_ray(v.camera, px, py, o, d);
    const float want = dist - ball.radius;
    for (int k = 0; k < 3; ++k) CHECK(o[k] + want * d[k] == doctest::Approx(q[k]).epsilon(1e-4));
    SurfaceHit h = truth.trace({o[0], o[1], o[2]}, {d[0], d[1], d[2]});
    REQUIRE(h.hit);
    CHECK(h.t <= want + 1e-4f);
    if (std::fabs(h.t - want) < 1e-4f) ++unoccluded;
  }
  CHECK(unoccluded >= 4);
}

TEST_CASE("rays: unit directions, principal point looks forward, sampler matches camera rays") {
  Scene s = load_scene(generated_scene(), quiet());
  const Camera& c = s.train[2].camera;
  float o[3], d[3];
  pixel_ray(c, c.cx, c.cy, o, d);
  auto f = c.forward();
  for (int k = 0; k < 3; ++k) CHECK(d[k] == doctest::Approx(f[k]).epsilon(1e-6));
  Rays all = camera_rays(s, c);
  REQUIRE(all.size() == 32u * 32u);
  for (size_t i = 0; i < all.size(); ++i) {
    double n = std::hypot(all.directions[3 * i], all.directions[3 * i + 1], all.directions[3 * i + 2]);
    CHECK(n == doctest::Approx(1.0).epsilon(1e-6));
  }
  // Pixel (x, y) = (0, 0) is the top-left: its ray goes left (-x cam) and up (+y cam).
  float cam_dir[3];
  for (int k = 0; k < 3; ++k)
    cam_dir[k] = c.c2w[0][k] * all.directions[0] + c.c2w[1][k] * all.directions[1] + c.c2w[2][k] * all.directions[2];
  CHECK(cam_dir[0] < 0);
  CHECK(cam_dir[1] > 0);

  RaySampler a(s, 7), b(s, 7);
  Rays ra = a.next(256), rb = b.next(256);
  CHECK(ra.origins == rb.origins);
  CHECK(ra.rgb == rb.rgb);
  const size_t per = 32 * 32;
  for (int i = 0; i < 256; ++i) {
    const View& v = s.train[ra.pixel[i] / per];
    const size_t local = ra.pixel[i] % per;
    Rays ref = camera_rays(s, v.camera);
    for (int k = 0; k < 3; ++k) {
      CHECK(ra.directions[3 * i + k] == ref.directions[3 * local + k]);
      CHECK(ra.rgb[3 * i + k] == v.rgb[3 * local + k]);
    }
    if (i > 16) break;  // a handful is enough; camera_rays per sample is the slow part
  }
}

TEST_CASE("NDC: origins on the near plane, points map by the formula, t = 1 is infinity") {
  Camera c;
  c.width = 40;
  c.height = 30;
  c.fx = 35;
  c.fy = 33;
  c.cx = 20;
  c.cy = 15;
  // Hand-computed: p = (0.5, -0.25, -2), near 1: x = -1.75 * (0.5/-2) = 0.4375, y = -2.2 * (-0.25/-2) = -0.275,
  // z = 1 + 2/-2 = 0.
  auto q = ndc_point(c, 1.0f, {0.5f, -0.25f, -2.0f});
  CHECK(q[0] == doctest::Approx(0.4375));
  CHECK(q[1] == doctest::Approx(-0.275));
  CHECK(q[2] == doctest::Approx(0.0));

  for (float px : {0.5f, 13.0f, 39.5f})
    for (float py : {0.5f, 22.0f}) {
      float o[3], d[3];
      pixel_ray(c, px, py, o, d);
      float wo[3] = {o[0], o[1], o[2]}, wd[3] = {d[0], d[1], d[2]};
      to_ndc(c, 1.0f, o, d);
      CHECK(o[2] == doctest::Approx(-1.0f).epsilon(1e-6));  // near plane
      for (float dist : {1.5f, 3.0f, 50.0f}) {
        std::array<float, 3> p{wo[0] + dist * wd[0], wo[1] + dist * wd[1], wo[2] + dist * wd[2]};
        auto n = ndc_point(c, 1.0f, p);
        const float t = (n[2] - o[2]) / d[2];
        CHECK(t >= 0.0f);
        CHECK(t <= 1.0f);
        CHECK(o[0] + t * d[0] == doctest::Approx(n[0]).epsilon(1e-4));
        CHECK(o[1] + t * d[1] == doctest::Approx(n[1]).epsilon(1e-4));
      }
      CHECK(o[2] + d[2] == doctest::Approx(1.0f).epsilon(1e-6));  // t = 1: z -> infinity
    }
}

TEST_CASE("camera paths: orbit looks at the origin at the training radius") {
  Scene s = load_scene(generated_scene(), quiet());
  auto path = default_path(s, 12);
  REQUIRE(path.size() == 12);
  for (const Camera& c : path) {
    auto p = c.position();
    auto f = c.forward();
    const double r = std::hypot(p[0], p[1], p[2]);
    CHECK(r == doctest::Approx(4.0).epsilon(1e-4));
    CHECK(-(p[0] * f[0] + p[1] * f[1] + p[2] * f[2]) / r == doctest::Approx(1.0).epsilon(1e-5));
    CHECK(c.width == 32);
  }
}

// ------------------------------------------------------------------------------------------------
TEST_CASE("real lego at 1/4: 200x200, counts, intrinsics, white background" * doctest::test_suite("shared")) {
  const std::string root = data_dir();
  REAL_DATA_OR_RETURN(root, "the real lego");
  Scene s = load_scene(root + "/scenes/blender/lego", quiet(4));
  CHECK(s.train.size() == 100);
  CHECK(s.test.size() == 25);
  CHECK(s.width() == 200);
  CHECK(s.height() == 200);
  CHECK(s.train[0].camera.fx == doctest::Approx(0.5 * 200 / std::tan(0.5 * 0.6911112070083618)).epsilon(1e-5));
  CHECK(s.effects.background);
  CHECK_FALSE(s.effects.ndc);
  CHECK(s.near == 2.0f);
  CHECK(s.far == 6.0f);
  CHECK(s.aabb[0][0] == -1.5f);
  CHECK(s.train[0].rgb[0] == doctest::Approx(1.0f));  // corner: background composited on white
  CHECK(s.train[0].rgb.size() == 200u * 200u * 3u);
  CHECK(has(s.describe(), "background colour"));
}

TEST_CASE("real fern at 1/8: 504x378, 17 train / 3 test, NDC, recentred and rescaled" * doctest::test_suite("shared")) {
  const std::string root = data_dir();
  REAL_DATA_OR_RETURN(root, "the real fern");
  Scene s = load_scene(root + "/scenes/llff/fern", quiet(8));
  CHECK(s.format == "llff-forward");
  CHECK(s.width() == 504);
  CHECK(s.height() == 378);
  CHECK(s.train.size() == 17);
  CHECK(s.test.size() == 3);
  CHECK(s.test[1].image_path.find("image008") != std::string::npos);  // every 8th held out
  CHECK(s.effects.ndc);
  CHECK_FALSE(s.effects.background);
  CHECK(s.near == 0.0f);
  CHECK(s.far == 1.0f);
  CHECK(s.aabb[1][1] == doctest::Approx(1.67f));
  CHECK(s.depth_near == doctest::Approx(1.0 / 0.75).epsilon(1e-5));
  CHECK(s.train[0].camera.fx == doctest::Approx(3260.5263328805895 / 8).epsilon(1e-5));
  // Recentred: the mean camera position is the origin and the cameras look down -z.
  double mean[3] = {0, 0, 0}, fz = 0;
  std::vector<View> all = s.train;
  all.insert(all.end(), s.test.begin(), s.test.end());
  for (const View& v : all) {
    for (int k = 0; k < 3; ++k) mean[k] += v.camera.position()[k] / all.size();
    fz += v.camera.forward()[2] / all.size();
  }
  for (int k = 0; k < 3; ++k) CHECK(std::fabs(mean[k]) < 1e-5);
  CHECK(fz < -0.98);
  // NDC rays start on the near plane (NDC z = -1) and stay inside the box in x, y there.
  Rays r = camera_rays(s, s.test[0].camera);
  for (size_t i = 0; i < r.size(); i += 97) {
    CHECK(r.origins[3 * i + 2] == doctest::Approx(-1.0f).epsilon(1e-5));
    CHECK(std::fabs(r.origins[3 * i]) < 1.5f);
    CHECK(std::fabs(r.origins[3 * i + 1]) < 1.67f);
  }
  CHECK(has(s.describe(), "NDC rays"));
  auto spiral = default_path(s, 30);
  CHECK(spiral.size() == 30);
  for (const Camera& c : spiral) CHECK(c.forward()[2] < -0.9f);
}

TEST_CASE("object capture (cup at 1/4): object-centric, no NDC, centred box, cameras at distance ~1" * doctest::test_suite("shared")) {
  const std::string root = data_dir();
  REAL_DATA_OR_RETURN(root, "the real cup capture");
  Scene s = load_scene(root + "/scenes/llff/cup", quiet(4));
  CHECK(s.format == "llff-object");
  CHECK_FALSE(s.effects.ndc);
  CHECK(s.width() == 200);
  CHECK(s.height() == 150);
  CHECK(s.train.size() + s.test.size() == 77);
  CHECK(s.test.size() == 10);
  CHECK(s.train[0].camera.fx == doctest::Approx(589.0271238562469 / 4).epsilon(1e-5));
  double mean = 0;
  for (const View& v : s.train) {
    auto p = v.camera.position();
    mean += std::hypot(p[0], p[1], p[2]) / s.train.size();
    for (int k = 0; k < 3; ++k) {  // cameras outside the box, looking towards its centre
      CHECK(s.aabb[0][k] < 0);
      CHECK(s.aabb[1][k] > 0);
    }
    auto f = v.camera.forward();
    CHECK(-(p[0] * f[0] + p[1] * f[1] + p[2] * f[2]) / std::hypot(p[0], p[1], p[2]) > 0.8);
  }
  CHECK(mean == doctest::Approx(1.0).epsilon(0.1));
  CHECK(has(s.describe(), "object-centric"));

  LoadOptions forced = quiet(4);
  forced.ndc = Switch::on;
  forced.load_images = false;
  Scene f = load_scene(root + "/scenes/llff/cup", forced);
  CHECK(f.effects.ndc);
  CHECK(has(f.describe(), "NDC forced on"));
}

// ------------------------------------------------------------------------------------------------
// A view of w x h whose border ring (the outer `ring` pixels) is `border` and whose interior is a texture.
View bordered_view(int w, int h, int ring, std::function<std::array<float, 3>(int, int)> border) {
  View v;
  v.camera.width = w;
  v.camera.height = h;
  v.rgb.resize(size_t(w) * h * 3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const bool edge = x < ring || y < ring || x >= w - ring || y >= h - ring;
      const std::array<float, 3> c = edge ? border(x, y)
                                          : std::array<float, 3>{float((x * 37 + y * 11) % 97) / 97.0f, float((x * y) % 53) / 53.0f, 0.2f};
      for (int k = 0; k < 3; ++k) v.rgb[(size_t(y) * w + x) * 3 + k] = c[size_t(k)];
    }
  return v;
}

TEST_CASE("plain backdrop: an object capture on a uniform border gets its colour as background, others do not") {
  // 100 x 60: the ring looked at is 60 / 50 = 1 pixel wide; the fixtures' borders are 3 wide.
  auto near_white = [](int x, int y) { return std::array<float, 3>{0.98f + 0.01f * float((x + y) % 3), 0.99f, 0.97f}; };
  auto busy = [](int x, int y) { return std::array<float, 3>{float((x * 7 + y * 3) % 10) / 10.0f, 0.5f, 0.4f}; };
  Scene object;
  object.format = "llff-object";
  for (int i = 0; i < 4; ++i) object.train.push_back(bordered_view(100, 60, 3, near_white));
  const BorderColour b = border_colour(object.train);
  CHECK(b.pixels == 4 * (2 * 100 + 2 * 58));
  CHECK(b.share == doctest::Approx(1.0));
  CHECK(b.rgb[1] == doctest::Approx(0.99f));

  Scene masked = object;
  detect_plain_background(masked);
  CHECK(masked.effects.background);
  CHECK(masked.effects.background_rgb[0] == doctest::Approx(0.99f));
  CHECK(masked.effects.background_rgb[2] == doctest::Approx(0.97f));
  CHECK(has(masked.describe(), "background colour (0.99, 0.99, 0.97) (plain backdrop)"));
  CHECK(has(masked.describe(), "100% of the training views' border pixels"));

  Scene forward = object;  // NDC rays never leave the content: no background whatever the border
  forward.format = "llff-forward";
  detect_plain_background(forward);
  CHECK_FALSE(forward.effects.background);

  Scene real = object;  // a real backdrop: its border pixels spread over many colours
  for (View& v : real.train) v = bordered_view(100, 60, 3, busy);
  CHECK(border_colour(real.train).share < kUniformBorderShare);
  detect_plain_background(real);
  CHECK_FALSE(real.effects.background);

  Scene mostly = object;  // one view in four with a busy border: 75% uniform, below the 95% asked for
  mostly.train[2] = bordered_view(100, 60, 3, busy);
  detect_plain_background(mostly);
  CHECK_FALSE(mostly.effects.background);

  Scene alpha = object;  // a background from alpha is kept as it is
  alpha.effects.background = true;
  alpha.effects.background_rgb = {0, 0, 0};
  detect_plain_background(alpha);
  CHECK(alpha.effects.background_rgb[0] == 0.0f);
  CHECK(alpha.effects.background_reason == "images have alpha");

  Scene cameras_only = object;  // nothing to read the border from
  for (View& v : cameras_only.train) v.rgb.clear();
  detect_plain_background(cameras_only);
  CHECK_FALSE(cameras_only.effects.background);
  CHECK(border_colour(cameras_only.train).pixels == 0);
}

TEST_CASE("backdrop pixels: alpha below the threshold, or the backdrop colour reached from the border") {
  // 12 x 8 on white: a 6 x 4 object at (3..8, 2..5) drawn as a red frame around a white label (5..6, 3..4),
  // plus a near-white pixel of JPEG noise on the backdrop at (0, 7) and a grey one at (11, 0).
  const int w = 12, h = 8;
  View v;
  v.camera.width = w;
  v.camera.height = h;
  v.rgb.assign(size_t(w) * h * 3, 1.0f);
  auto set = [&](int x, int y, std::array<float, 3> c) {
    for (int k = 0; k < 3; ++k) v.rgb[(size_t(y) * w + x) * 3 + k] = c[size_t(k)];
  };
  for (int y = 2; y <= 5; ++y)
    for (int x = 3; x <= 8; ++x) set(x, y, {0.8f, 0.1f, 0.1f});
  for (int y = 3; y <= 4; ++y)
    for (int x = 5; x <= 6; ++x) set(x, y, {1.0f, 1.0f, 1.0f});
  set(0, 7, {0.96f, 0.97f, 0.99f});
  set(11, 0, {0.5f, 0.5f, 0.5f});
  Scene s;
  s.format = "llff-object";
  s.train.push_back(v);
  CHECK(backdrop_pixels(s, v).empty());  // no background: no backdrop
  s.effects.background = true;
  s.effects.background_rgb = {1, 1, 1};
  s.effects.background_reason = "plain backdrop";
  const auto m = backdrop_pixels(s, v);
  REQUIRE(m.size() == size_t(w * h));
  auto at = [&](int x, int y) { return int(m[size_t(y) * w + x]); };
  CHECK(at(0, 0) == 1);
  CHECK(at(0, 7) == 1);   // within the tolerance
  CHECK(at(11, 0) == 0);  // another colour
  CHECK(at(3, 2) == 0);   // the object
  CHECK(at(5, 3) == 0);   // white, but enclosed by the object: the label, not the backdrop
  CHECK(at(6, 4) == 0);
  CHECK(at(9, 3) == 1);
  int n = 0;
  for (uint8_t b : m) n += b;
  CHECK(n == w * h - 6 * 4 - 1);

  View a = v;  // with alpha, alpha decides, whatever the colour
  a.alpha.assign(size_t(w) * h, 1.0f);
  a.alpha[0] = 0.0f;
  a.alpha[1] = 0.5f * kBackdropAlpha;
  a.alpha[2] = 2.0f * kBackdropAlpha;
  const auto ma = backdrop_pixels(s, a);
  REQUIRE(ma.size() == size_t(w * h));
  CHECK(ma[0] == 1);
  CHECK(ma[1] == 1);
  CHECK(ma[2] == 0);
  CHECK(ma[size_t(7) * w] == 0);

  View empty = v;  // cameras only: nothing to read
  empty.rgb.clear();
  CHECK(backdrop_pixels(s, empty).empty());
}

TEST_CASE("plain backdrop on the real captures: milk_carton (masked to white) on, cup (a room behind it) off" * doctest::test_suite("shared")) {
  const std::string root = data_dir();
  REAL_DATA_OR_RETURN(root, "the real object captures' backgrounds");
  Scene milk = load_scene(root + "/scenes/llff/milk_carton", quiet(8));
  CHECK(milk.format == "llff-object");
  CHECK(milk.effects.background);
  for (float c : milk.effects.background_rgb) CHECK(c > 0.95f);
  // The backdrop pixels of the masked capture: most of each view, never the whole of it.
  for (const View& v : {milk.train[0], milk.test[0]}) {
    const auto m = backdrop_pixels(milk, v);
    REQUIRE(m.size() == size_t(v.camera.width) * size_t(v.camera.height));
    double share = 0;
    for (uint8_t b : m) share += b;
    share /= double(m.size());
    CHECK(share > 0.5);
    CHECK(share < 0.98);
  }
  Scene cup = load_scene(root + "/scenes/llff/cup", quiet(4));
  CHECK_FALSE(cup.effects.background);
  CHECK(backdrop_pixels(cup, cup.train[0]).empty());
}

TEST_CASE("bad Blender inputs give errors naming the file") {
  TempDir t("bad_blender");
  auto fresh = [&](const std::string& name) {
    fs::path p = t.path / name;
    fs::copy(generated_scene(), p, fs::copy_options::recursive);
    return p;
  };
  {
    fs::path p = fresh("no_train");
    fs::remove(p / "transforms_train.json");
    std::string e = error_of([&] { load_scene(p.string(), quiet()); });
    CHECK(has(e, "transforms_train.json is missing"));
  }
  {
    fs::path p = fresh("no_test");
    fs::remove(p / "transforms_test.json");
    CHECK(has(error_of([&] { load_scene(p.string(), quiet()); }), "transforms_test.json is missing"));
  }
  {
    fs::path p = fresh("no_image");
    fs::remove(p / "train" / "r_3.png");
    CHECK(has(error_of([&] { load_scene(p.string(), quiet()); }), "r_3.png does not exist"));
  }
  {
    fs::path p = fresh("garbage_image");
    host::write_file_atomic((p / "train" / "r_2.png").string(), "this is not a png");
    std::string e = error_of([&] { load_scene(p.string(), quiet()); });
    CHECK(has(e, "r_2.png"));
    CHECK(has(e, "cannot read image"));
  }
  {
    fs::path p = fresh("other_size");
    std::vector<unsigned char> px(16 * 16 * 4, 255);
    REQUIRE(stbi_write_png((p / "train" / "r_5.png").string().c_str(), 16, 16, 4, px.data(), 16 * 4));
    std::string e = error_of([&] { load_scene(p.string(), quiet()); });
    CHECK(has(e, "r_5.png is 16x16"));
    CHECK(has(e, "one size"));
  }
  {
    fs::path p = fresh("null_pose");
    auto j = nlohmann::json::parse(host::read_file((p / "transforms_train.json").string()));
    j["frames"][1]["transform_matrix"][0][2] = nullptr;  // how a NaN often ends up in JSON
    host::write_file_atomic((p / "transforms_train.json").string(), j.dump());
    std::string e = error_of([&] { load_scene(p.string(), quiet()); });
    CHECK(has(e, "transforms_train.json frame 1"));
    CHECK(has(e, "is not a number"));
  }
  {
    fs::path p = fresh("string_pose");
    auto j = nlohmann::json::parse(host::read_file((p / "transforms_train.json").string()));
    j["frames"][2]["transform_matrix"][1][1] = "0.5";
    host::write_file_atomic((p / "transforms_train.json").string(), j.dump());
    std::string e = error_of([&] { load_scene(p.string(), quiet()); });
    CHECK(has(e, "transforms_train.json frame 2"));
    CHECK(has(e, "is not a number: \"0.5\""));
  }
  {
    fs::path p = fresh("zero_pose");  // a degenerate matrix: NaN cameras if accepted
    auto j = nlohmann::json::parse(host::read_file((p / "transforms_train.json").string()));
    j["frames"][3]["transform_matrix"] = nlohmann::json::array({{0, 0, 0, 0}, {0, 0, 0, 0}, {0, 0, 0, 0}, {0, 0, 0, 1}});
    host::write_file_atomic((p / "transforms_train.json").string(), j.dump());
    std::string e = error_of([&] { load_scene(p.string(), quiet()); });
    CHECK(has(e, "transforms_train.json frame 3"));
    CHECK(has(e, "not a rigid transform"));
  }
  {
    fs::path p = fresh("scaled_pose");  // a rotation scaled by 2
    auto j = nlohmann::json::parse(host::read_file((p / "transforms_test.json").string()));
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) j["frames"][0]["transform_matrix"][r][c] = 2 * j["frames"][0]["transform_matrix"][r][c].get<double>();
    host::write_file_atomic((p / "transforms_test.json").string(), j.dump());
    CHECK(has(error_of([&] { load_scene(p.string(), quiet()); }), "not a rigid transform"));
  }
  {
    fs::path p = fresh("nan_text");
    std::string text = host::read_file((p / "transforms_train.json").string());
    text.replace(text.find("\"transform_matrix\": [") + 21, 0, "[NaN, 0, 0, 0],");  // Python's json.dump
    host::write_file_atomic((p / "transforms_train.json").string(), text);
    std::string e = error_of([&] { load_scene(p.string(), quiet()); });
    CHECK(has(e, "transforms_train.json"));
  }
  CHECK(has(error_of([&] { load_scene(t.str("does_not_exist"), quiet()); }), "does not exist"));
}

TEST_CASE("bad LLFF inputs: count mismatch, NaN pose, wrong shape, different sizes") {
  TempDir t("bad_llff");
  const LlffFixture fixture = write_llff_images(t.path / "source");
  auto fresh = [&](const std::string& name, size_t rows, std::function<void(std::vector<float>&)> edit) {
    fs::path p = t.path / name;
    fs::create_directories(p);
    fs::copy(t.path / "source" / "images_8", p / "images_8", fs::copy_options::recursive);
    std::vector<float> v(fixture.poses.begin(), fixture.poses.begin() + rows * 17);
    if (edit) edit(v);
    io::write_npy_f32((p / "poses_bounds.npy").string(), {rows, 17}, v);
    return p;
  };
  {
    fs::path p = fresh("ok", 20, nullptr);  // float32 copy loads like the original
    LoadOptions o = quiet(8);
    o.load_images = false;
    Scene s = load_scene(p.string(), o);
    CHECK(s.train.size() == 17);
    CHECK(s.effects.ndc);
  }
  {
    fs::path p = fresh("count", 19, nullptr);
    std::string e = error_of([&] { load_scene(p.string(), quiet(8)); });
    CHECK(has(e, "poses_bounds.npy has 19 poses"));
    CHECK(has(e, "images_8 has 20 images"));
  }
  {
    fs::path p = fresh("nan", 20, [](std::vector<float>& v) { v[5 * 17 + 3] = std::nanf(""); });
    std::string e = error_of([&] { load_scene(p.string(), quiet(8)); });
    CHECK(has(e, "poses_bounds.npy: pose 5 has a non-finite entry"));
  }
  {
    // A zeroed pose once reclassified fern as an object capture; now it is refused, naming the pose.
    fs::path p = fresh("zero", 20, [](std::vector<float>& v) {
      for (int k = 0; k < 15; ++k) v[7 * 17 + k] = 0.0f;
    });
    std::string e = error_of([&] { load_scene(p.string(), quiet(8)); });
    CHECK(has(e, "poses_bounds.npy: pose 7"));
    CHECK(has(e, "not a rigid transform"));
  }
  {
    fs::path p = fresh("inf", 20, [](std::vector<float>& v) { v[2 * 17 + 16] = INFINITY; });
    CHECK(has(error_of([&] { load_scene(p.string(), quiet(8)); }), "pose 2 has a non-finite entry"));
  }
  {
    fs::path p = fresh("shape", 20, nullptr);
    std::vector<float> v(20 * 15, 1.0f);
    io::write_npy_f32((p / "poses_bounds.npy").string(), {20, 15}, v);
    std::string e = error_of([&] { load_scene(p.string(), quiet(8)); });
    CHECK(has(e, "poses_bounds.npy"));
    CHECK(has(e, "shape (20, 15)"));
  }
  {
    fs::path p = fresh("size", 20, nullptr);
    std::vector<unsigned char> px(50 * 40 * 3, 128);
    REQUIRE(stbi_write_png((p / "images_8" / "image011.png").string().c_str(), 50, 40, 3, px.data(), 50 * 3));
    std::string e = error_of([&] { load_scene(p.string(), quiet(8)); });
    CHECK(has(e, "image011.png is 50x40"));
  }
  {
    fs::path p = fresh("unreadable", 20, nullptr);
    host::write_file_atomic((p / "images_8" / "image004.png").string(), "garbage");
    std::string e = error_of([&] { load_scene(p.string(), quiet(8)); });
    CHECK(has(e, "image004.png"));
  }
  {
    fs::path p = fresh("folder", 20, nullptr);
    std::string e = error_of([&] { load_scene(p.string(), quiet(4)); });
    CHECK(has(e, "no image folder for downsample 4"));
  }
}

TEST_CASE("make-scene refuses to overwrite other data and replaces its own output") {
  TempDir t("overwrite");
  host::write_file_atomic(t.str("precious/keep.txt"), "mine");
  MakeSceneOptions o;
  o.size = 8;
  o.views = 6;
  CHECK(has(error_of([&] { make_scene(t.str("precious"), o); }), "refusing to overwrite"));
  CHECK(fs::exists(t.path / "precious" / "keep.txt"));
  make_scene(t.str("gen"), o);
  make_scene(t.str("gen"), o);  // its own output is replaced
  CHECK(fs::exists(t.path / "gen" / "transforms_val.json"));
  for (const auto& e : fs::directory_iterator(t.path)) CHECK(e.path().filename().string().find(".partial") == std::string::npos);
}

TEST_CASE("downsample by default: the paper's resolution, Blender 1 and LLFF 4; a given factor is kept") {
  testing::TempDir tmp("test_scene", "downsample");
  const fs::path blender = tmp.path / "blender", llff = tmp.path / "llff", colmap = tmp.path / "colmap";
  for (const fs::path& d : {blender, llff, colmap}) fs::create_directories(d);
  std::ofstream(blender / "transforms_train.json") << "{}";
  std::ofstream(llff / "poses_bounds.npy") << "";
  CHECK(scene::resolve_downsample(blender.string(), 0) == 1);
  CHECK(scene::resolve_downsample(llff.string(), 0) == 4);  // 1008x756 from 4032x3024
  CHECK(scene::resolve_downsample(colmap.string(), 0) == 1);
  CHECK(scene::resolve_downsample(llff.string(), 8) == 8);
  CHECK(scene::resolve_downsample(blender.string(), 2) == 2);
  testing::expect_error([&] { scene::resolve_downsample(blender.string(), -1); }, "at least 1, or 0 for the scene's default");
  // LLFF captures of smaller images: the longer side of images/ brought to at most 1024, by powers of two.
  fs::create_directories(llff / "images");
  auto llff_default_for = [&](int w, int h) {
    for (const auto& e : fs::directory_iterator(llff / "images")) fs::remove(e.path());
    io::Image im;
    im.width = w, im.height = h;
    im.data.assign(size_t(3) * w * h, 0.5f);
    io::save_png((llff / "images" / "000.png").string(), im);
    return scene::resolve_downsample(llff.string(), 0);
  };
  CHECK(llff_default_for(4032, 30) == 4);  // 4032x3024 captures: 1008x756, the paper's
  CHECK(llff_default_for(544, 960) == 1);    // an object capture at its own size
  CHECK(llff_default_for(1140, 855) == 2);   // 570x428
  CHECK(llff_default_for(1024, 768) == 1);
  CHECK(llff_default_for(1025, 20) == 2);
}
