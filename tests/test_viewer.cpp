// The live viewer's library side: camera offsets (exact at zero, orbits keep the distance, elevation and
// forward-facing spans clamped), the fair scheduler (newest request wins, a running one is cancelled, turns
// alternate, stop answers everyone), the content render's cancel flag, the style library's refusals, and the
// frame renderer (a cached content gives the same frame; the full frame is the model's own inference).
#include <doctest/doctest.h>

#include <chrono>
#include <cmath>
#include <fstream>
#include <thread>

#include "host/error.hpp"
#include "lib/io/checkpoint.hpp"
#include "lib/io/image.hpp"
#include "lib/model/scene_style_stats.hpp"
#include "lib/model/style_model.hpp"
#include "lib/nn/vgg.hpp"
#include "lib/scene/view_offset.hpp"
#include "lib/style/style_encoder.hpp"
#include "lib/viewer/fair_scheduler.hpp"
#include "lib/viewer/frame_renderer.hpp"
#include "lib/viewer/style_library.hpp"
#include "tests/small_scene.hpp"
#include "tests/testing.hpp"

using namespace stylerf;
using viewer::FairScheduler;

namespace {

double length(const std::array<float, 3>& p) { return std::sqrt(double(p[0]) * p[0] + double(p[1]) * p[1] + double(p[2]) * p[2]); }

// A forward-facing capture of five cameras on a small cross, all looking down -z.
scene::Scene forward_scene() {
  scene::Scene s;
  s.name = "cross";
  s.format = "llff-forward";
  s.effects.ndc = true;
  s.depth_near = 2;
  s.depth_far = 10;
  const float xy[5][2] = {{0, 0}, {0.2f, 0}, {-0.2f, 0}, {0, 0.1f}, {0, -0.1f}};
  for (const auto& p : xy) {
    scene::View v;
    v.camera.c2w[0][3] = p[0];
    v.camera.c2w[1][3] = p[1];
    v.camera.width = 64;
    v.camera.height = 48;
    v.camera.fx = v.camera.fy = 60;
    v.camera.cx = 32;
    v.camera.cy = 24;
    s.train.push_back(v);
  }
  return s;
}

}  // namespace

TEST_CASE("a zero offset is the training view itself; an orbit keeps the distance and turns about the up axis") {
  const scene::Scene& s = testing::small_scene();
  REQUIRE(scene::view_kind(s) == scene::ViewKind::Orbit);
  const scene::Camera& base = s.train[3].camera;
  const scene::Camera same = scene::offset_camera(s, {3, 0, 0, 0});
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 4; ++k) CHECK(same.c2w[r][k] == base.c2w[r][k]);

  const double yaw = 0.7;
  const scene::Camera turned = scene::offset_camera(s, {3, yaw, 0, 0});
  CHECK(length(turned.position()) == doctest::Approx(length(base.position())).epsilon(1e-5));
  // About +z through the origin: z unchanged, the azimuth advanced by yaw.
  CHECK(turned.position()[2] == doctest::Approx(base.position()[2]).epsilon(1e-5));
  const double az0 = std::atan2(base.position()[1], base.position()[0]);
  const double az1 = std::atan2(turned.position()[1], turned.position()[0]);
  CHECK(std::remainder(az1 - az0 - yaw, 2 * M_PI) == doctest::Approx(0).epsilon(1e-5));
  // The view keeps its angle to the centre (a rigid turn of the whole camera).
  auto angle_to_centre = [](const scene::Camera& c) {
    const auto p = c.position(), f = c.forward();
    return -(double(p[0]) * f[0] + double(p[1]) * f[1] + double(p[2]) * f[2]) / length(p);
  };
  CHECK(angle_to_centre(turned) == doctest::Approx(angle_to_centre(base)).epsilon(1e-5));

  // Elevation never passes kMaxElevation, however far the pitch asks.
  const scene::Camera top = scene::offset_camera(s, {3, 0, 100, 0});
  CHECK(std::asin(top.position()[2] / length(top.position())) == doctest::Approx(scene::kMaxElevation).epsilon(1e-4));
  const scene::Camera near = scene::offset_camera(s, {3, 0, 0, 0.5});
  CHECK(length(near.position()) == doctest::Approx(length(base.position()) * std::exp(-0.5)).epsilon(1e-5));
  // Zoom is clamped to its limits.
  const scene::Camera far = scene::offset_camera(s, {3, 0, 0, -50});
  CHECK(length(far.position()) == doctest::Approx(length(base.position()) * std::exp(1.0)).epsilon(1e-5));
  // The size follows `longer`.
  CHECK(std::max(scene::offset_camera(s, {3, 0, 0, 0}, 20).width, scene::offset_camera(s, {3, 0, 0, 0}, 20).height) == 20);
}

TEST_CASE("forward-facing offsets stay within the capture's span and keep looking at the same point") {
  const scene::Scene s = forward_scene();
  REQUIRE(scene::view_kind(s) == scene::ViewKind::Forward);
  const scene::Camera a = scene::offset_camera(s, {0, 1, 0, 0});
  const scene::Camera b = scene::offset_camera(s, {0, 7, 0, 0});  // clamped to 1
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 4; ++k) CHECK(a.c2w[r][k] == doctest::Approx(b.c2w[r][k]));
  // Moved right by the span's 90th percentile (0.2), up not at all.
  CHECK(a.position()[0] == doctest::Approx(0.2).epsilon(1e-4));
  CHECK(a.position()[1] == doctest::Approx(0.0).epsilon(1e-4));
  // The point the training view looked at still projects to the image centre.
  const double close = 2 * 0.9, inf = 10 * 5.0, focal = 1.0 / (0.25 / close + 0.75 / inf);
  float px = 0, py = 0;
  REQUIRE(a.project({0, 0, float(-focal)}, px, py));
  CHECK(px == doctest::Approx(32).epsilon(1e-3));
  CHECK(py == doctest::Approx(24).epsilon(1e-3));
  // Every orbit frame within the limits.
  for (const auto& o : scene::orbit_offsets({0, 0.8, 0, 0}, scene::ViewKind::Forward, 12)) {
    CHECK(std::abs(o.yaw) <= 1.0);
    CHECK(std::abs(o.pitch) <= 1.0);
  }
}

TEST_CASE("camera offsets refuse a view that does not exist and numbers that are not finite") {
  const scene::Scene& s = testing::small_scene();
  testing::expect_error([&] { scene::offset_camera(s, {int(s.train.size()), 0, 0, 0}); }, "not a training view");
  testing::expect_error([&] { scene::offset_camera(s, {-1, 0, 0, 0}); }, "not a training view");
  testing::expect_error([&] { scene::offset_camera(s, {0, std::nan(""), 0, 0}); }, "finite");
  testing::expect_error([&] { scene::offset_camera(s, {0, 0, INFINITY, 0}); }, "finite");
}

TEST_CASE("the scheduler keeps each client's newest work and cancels the running one") {
  FairScheduler sch;
  std::atomic<bool> started{false};
  FairScheduler::Outcome first = FairScheduler::Outcome::Done;
  std::thread t([&] {
    first = sch.run("tab", [&](const std::atomic<bool>& cancel) {
      started = true;
      while (!cancel) std::this_thread::sleep_for(std::chrono::milliseconds(1));  // a long render
    });
  });
  while (!started) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  bool ran = false;
  CHECK(sch.run("tab", [&](const std::atomic<bool>&) { ran = true; }) == FairScheduler::Outcome::Done);
  t.join();
  CHECK(first == FairScheduler::Outcome::Superseded);
  CHECK(ran);
  CHECK(sch.superseded() == 1);
}

TEST_CASE("pending work replaced by a newer request never runs; clients take turns") {
  FairScheduler sch;
  std::atomic<bool> hold{true}, started{false};
  std::vector<std::string> order;
  std::mutex order_mu;
  auto note = [&](const std::string& what) {
    return [&, what](const std::atomic<bool>&) {
      std::lock_guard<std::mutex> lock(order_mu);
      order.push_back(what);
    };
  };
  std::thread blocker([&] {
    sch.run("blocker", [&](const std::atomic<bool>&) {
      started = true;
      while (hold) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    });
  });
  while (!started) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  FairScheduler::Outcome p1 = FairScheduler::Outcome::Done;
  std::thread a([&] { p1 = sch.run("P", note("P1")); });
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  std::thread b([&] { sch.run("Q", note("Q1")); });
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  std::thread c([&] { sch.run("P", note("P2")); });  // replaces P1, keeps P's turn (before Q)
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  hold = false;
  blocker.join();
  a.join();
  b.join();
  c.join();
  CHECK(p1 == FairScheduler::Outcome::Superseded);
  REQUIRE(order.size() == 2);
  CHECK(order[0] == "P2");
  CHECK(order[1] == "Q1");
}

TEST_CASE("the scheduler passes the work's error to its caller, and stop answers everyone") {
  FairScheduler sch;
  CHECK_THROWS_WITH(sch.run("x", [](const std::atomic<bool>&) { throw host::Error("broken"); }), "broken");
  std::atomic<bool> started{false};
  FairScheduler::Outcome running = FairScheduler::Outcome::Done, waiting = FairScheduler::Outcome::Done;
  std::thread r([&] {
    running = sch.run("a", [&](const std::atomic<bool>& cancel) {
      started = true;
      while (!cancel) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    });
  });
  while (!started) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  std::thread w([&] { waiting = sch.run("b", [](const std::atomic<bool>&) {}); });
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  sch.stop();
  r.join();
  w.join();
  CHECK(running == FairScheduler::Outcome::Stopped);
  CHECK(waiting == FairScheduler::Outcome::Stopped);
  CHECK(sch.run("c", [](const std::atomic<bool>&) {}) == FairScheduler::Outcome::Stopped);
}

TEST_CASE("the style library refuses what is not an image and keeps nothing of it") {
  testing::TempDir dir("viewer", "styles");
  viewer::StyleLibrary lib(dir.str("uploads"));
  testing::expect_error([&] { lib.add_upload("not an image at all", "notes.txt"); }, "not an image");
  testing::expect_error([&] { lib.add_upload("", "empty.png"); }, "empty");
  CHECK(lib.list().empty());
  CHECK(std::filesystem::is_empty(dir.str("uploads")));
  // A real PNG (made by the library's own encoder) becomes a style with a thumbnail of kThumbSide.
  io::Image img;
  img.width = 300;
  img.height = 150;
  img.data = testing::random_uniform(size_t(3) * 300 * 150, 7, 0, 1);
  const std::string id = lib.add_upload(io::encode_png(img), "noise\x01\x7f.png");
  const auto e = lib.find(id);
  REQUIRE(e.has_value());
  CHECK(e->source == "upload");
  CHECK(e->name == "noise.png");  // control characters dropped
  const std::string thumb_path = dir.str("thumb.png");
  std::ofstream(thumb_path, std::ios::binary) << e->thumb_png;
  const io::Image thumb = io::load_image(thumb_path);
  CHECK(thumb.width == viewer::kThumbSide);
  CHECK(thumb.height == viewer::kThumbSide / 2);
  CHECK_FALSE(lib.find("s99").has_value());
}

TEST_CASE("encode_png round-trips to 8 bits") {
  testing::TempDir dir("viewer", "png");
  io::Image img;
  img.width = 17;
  img.height = 5;
  img.data = testing::random_uniform(size_t(3) * 17 * 5, 3, -0.2f, 1.2f);  // clamped to [0, 1]
  const std::string path = dir.str("x.png");
  std::ofstream(path, std::ios::binary) << io::encode_png(img);
  const io::Image back = io::load_image(path);
  REQUIRE(back.width == 17);
  REQUIRE(back.height == 5);
  for (size_t i = 0; i < img.data.size(); ++i)
    CHECK(std::abs(back.data[i] - std::clamp(img.data[i], 0.0f, 1.0f)) <= 0.5f / 255 + 1e-6f);
}

TEST_CASE("a raised cancel flag stops the content render before its next renderer call") {
  const auto ck = io::load_checkpoint(testing::small_stage_files().style, "");
  const model::StyleModel m = model::StyleModel::load(ck);
  const scene::Scene& s = testing::small_scene();
  std::atomic<bool> cancel{true};
  CHECK_THROWS_AS(m.render_camera_content(s, s.test[0].camera, 64, nullptr, 1, model::kRefineContrast,
                                          model::kMergeKeptPerRay, &cancel),
                  model::RenderCancelled);
  cancel = false;  // lowered: the same content as without a flag
  const auto with = m.render_camera_content(s, s.test[0].camera, 64, nullptr, 1, model::kRefineContrast,
                                            model::kMergeKeptPerRay, &cancel);
  const auto without = m.render_camera_content(s, s.test[0].camera, 64, nullptr, 1);
  testing::check_close(with.content.c.to_host(), testing::to_double(without.content.c.to_host()), 0, 0, "content");
}

TEST_CASE("the frame renderer's full frame is the model's inference; a cached content gives the same frame") {
  testing::TempDir dir("viewer", "frames");
  const auto ck = io::load_checkpoint(testing::small_stage_files().style, "");
  const model::StyleModel m = model::StyleModel::load(ck);
  const scene::Scene& s = testing::small_scene();
  auto vgg = nn::VggEncoder::load_default();
  style::StyleEncoder enc(m.dst, vgg, "");
  const model::SceneStyleStats stats(m, s, 2);
  viewer::StyleLibrary lib(dir.str("uploads"));
  io::Image img;
  img.width = img.height = 64;
  img.data = testing::random_uniform(size_t(3) * 64 * 64, 11, 0, 1);
  const std::string a = lib.add_upload(io::encode_png(img), "a.png");
  img.data = testing::random_uniform(size_t(3) * 64 * 64, 12, 0, 1);
  const std::string b = lib.add_upload(io::encode_png(img), "b.png");
  viewer::FrameRenderer r(m, s, lib, enc, stats);

  viewer::FrameRequest f;
  f.camera = {2, 0.4, -0.2, 0.1};
  f.style = a;
  f.side = r.full_side();
  const viewer::Frame first = r.render(f);
  CHECK_FALSE(first.content_cached);
  CHECK_FALSE(first.preview);
  const viewer::Frame again = r.render(f);
  CHECK(again.content_cached);
  testing::check_close(again.image.data, testing::to_double(first.image.data), 0, 0, "cached content");

  // The same frame by hand: the camera, its content at the checkpoint's rays a block, the attached code.
  const scene::Camera cam = scene::offset_camera(s, f.camera, f.side);
  const auto cc = m.render_camera_content(s, cam, 8192, nullptr, m.inference_supersample);
  style::StyleCode code = enc.encode(lib.find(a)->path).code;
  stats.attach(code);
  auto rgb = m.stylize_camera(cc, code, cam.width, cam.height);
  m.over_background(rgb, cc, cam.width, cam.height);
  std::vector<float> planar(rgb.size());
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x)
      for (int ch = 0; ch < 3; ++ch)
        planar[(size_t(ch) * cam.height + y) * cam.width + x] = rgb[(size_t(y) * cam.width + x) * 3 + ch];
  testing::check_close(first.image.data, testing::to_double(planar), 1e-5, 1e-5, "the model's own frame");

  // A preview of a mix and a region: smaller, finite; a region without a second style is refused.
  f.side = r.full_side() / 2;
  f.style_b = b;
  f.mix = 0.3;
  const viewer::Frame mixed = r.render(f);
  CHECK(mixed.preview);
  CHECK(std::max(mixed.image.width, mixed.image.height) == f.side);
  CHECK(testing::all_finite(mixed.image.data));
  f.region_shape = "sphere";
  CHECK(testing::all_finite(r.render(f).image.data));
  f.style_b.clear();
  testing::expect_error([&] { r.render(f); }, "second style");
}
