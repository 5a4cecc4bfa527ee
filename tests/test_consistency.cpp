// The consistency metric's geometry (lib/eval/warp.hpp) and scoring (lib/eval/consistency.hpp): exact
// warps of a generated scene with known depth give near-zero error, a known flicker raises RMSE by the
// expected amount, and borders, background, occlusion, depth 0 / inf / NaN and the NDC far end are masked.
#include <doctest/doctest.h>

#include <cmath>
#include <limits>

#include "lib/eval/consistency.hpp"
#include "lib/eval/lpips.hpp"
#include "lib/eval/path_consistency.hpp"
#include "lib/eval/path_frames.hpp"
#include "lib/model/density_model.hpp"
#include "lib/train/density_trainer.hpp"
#include "lib/eval/warp.hpp"
#include "lib/model/opacity_head.hpp"
#include "lib/scene/analytic_scene.hpp"
#include "lib/scene/poses.hpp"
#include "lib/scene/rays.hpp"
#include "tests/orbit_frames.hpp"
#include "tests/small_scene.hpp"
#include "tests/testing.hpp"

using namespace stylerf;
using eval::Correspondence;
using eval::FrameGeometry;
using eval::RaySpace;

namespace {

constexpr int kSize = testing::kOrbitSize;

using testing::analytic_frame;
using testing::orbit_camera;
using Frame = testing::AnalyticFrame;
using testing::object_options;

double mean_valid_difference(const io::Image& a, const io::Image& b, const Correspondence& c) {
  double sum = 0;
  int64_t n = 0;
  const size_t plane = size_t(a.width) * a.height;
  for (size_t i = 0; i < plane; ++i)
    if (c.valid[i])
      for (int ch = 0; ch < 3; ++ch) sum += double(a.data[ch * plane + i]) - b.data[ch * plane + i], ++n;
  return sum / double(n);
}

}  // namespace

TEST_CASE("world_point inverts the projection, in world space and in NDC") {
  const scene::Camera cam = orbit_camera(5);
  const RaySpace world{false, 1.0f};
  for (double t : {0.5, 2.0, 3.7, 40.0}) {
    const auto X = eval::world_point(cam, 17.25, 40.5, t, world);
    float px = 0, py = 0;
    REQUIRE(cam.project({float(X[0]), float(X[1]), float(X[2])}, px, py));
    CHECK(px == doctest::Approx(17.25).epsilon(1e-4));
    CHECK(py == doctest::Approx(40.5).epsilon(1e-4));
    const double r = std::sqrt(std::pow(X[0] - cam.c2w[0][3], 2) + std::pow(X[1] - cam.c2w[1][3], 2) +
                               std::pow(X[2] - cam.c2w[2][3], 2));
    CHECK(r == doctest::Approx(t).epsilon(1e-9));
  }
  // NDC (a forward-facing camera at the origin looking down -z): the NDC point of the world point must be
  // o' + t d' of the pixel's NDC ray, and t = 0 is the near plane.
  scene::Camera fwd;
  fwd.fx = fwd.fy = 60;
  fwd.cx = 32;
  fwd.cy = 24;
  fwd.width = 64;
  fwd.height = 48;
  const RaySpace ndc{true, 1.0f};
  for (double t : {0.0, 0.3, 0.9, 0.998}) {
    bool finite = false;
    const auto X = eval::world_point(fwd, 10.5, 30.5, t, ndc, 0.999, &finite);
    CHECK(finite);
    float o[3], d[3];
    scene::pixel_ray(fwd, 10.5f, 30.5f, o, d);
    scene::to_ndc(fwd, 1.0f, o, d);
    const auto p = scene::ndc_point(fwd, 1.0f, {float(X[0]), float(X[1]), float(X[2])});
    for (int a = 0; a < 3; ++a) CHECK(p[a] == doctest::Approx(o[a] + t * d[a]).epsilon(1e-4).scale(1));
    if (t == 0.0) CHECK(X[2] == doctest::Approx(-1.0));
  }
  bool finite = true;
  eval::world_point(fwd, 10.5, 30.5, 0.9995, ndc, 0.999, &finite);
  CHECK_FALSE(finite);  // the NDC far end is at infinity
}

TEST_CASE("warping the true images by the true depth leaves near-zero error on valid pixels") {
  const RaySpace space{false, 1.0f};
  // Geometry first: every valid correspondence lands on the same surface point, with the same colour.
  const scene::AnalyticScene textured = scene::AnalyticScene::objects();
  for (int k : {1, 7}) {
    const Frame t = analytic_frame(orbit_camera(k)), s = analytic_frame(orbit_camera(0));
    const Correspondence c = eval::correspond(t.geo, s.geo, space, object_options());
    INFO("k = " << k << ": valid " << c.stats.valid << ", background " << c.stats.background << ", occluded "
                << c.stats.occluded << ", off image " << c.stats.off_image);
    CHECK(c.stats.pixels() == int64_t(kSize) * kSize);
    CHECK(c.stats.valid > kSize * kSize / 8);  // the objects cover a good part of the view
    double worst_point = 0;
    int colour_flips = 0;  // a point within 1e-3 of a checker edge may show the neighbouring cell
    for (int y = 0; y < kSize; ++y)
      for (int x = 0; x < kSize; ++x) {
        const size_t i = size_t(y) * kSize + x;
        if (!c.valid[i]) continue;
        const auto X = eval::world_point(t.geo.camera, x + 0.5, y + 0.5, t.geo.depth[i], space);
        float o[3], d[3];
        scene::pixel_ray(s.geo.camera, c.x[i], c.y[i], o, d);
        const auto hit = textured.trace({o[0], o[1], o[2]}, {d[0], d[1], d[2]});
        REQUIRE(hit.hit);
        const auto colour = textured.shade(hit);
        double colour_error = 0;
        for (int a = 0; a < 3; ++a) {
          worst_point = testing::max_or_nan(worst_point, std::abs(double(hit.point[a]) - X[a]));
          colour_error = std::max(colour_error, std::abs(double(colour[a]) - t.image.data[a * kSize * kSize + i]));
        }
        colour_flips += colour_error > 1e-3;
      }
    CHECK(worst_point < 1e-3);
    CHECK(colour_flips <= c.stats.valid / 100);
    // The images: bilinear resampling of textures (checker edges) is the only error left, and it is
    // well below what the same pixels compared without the warp differ by.
    const io::Image warped = eval::warp_image(s.image, c, t.image);
    const double exact = eval::masked_rmse(t.image, warped, c.valid);
    const double unwarped = eval::masked_rmse(t.image, s.image, c.valid);
    CHECK(exact < 0.75 * unwarped);
  }
  // Without texture edges (plain materials) the resampled images agree almost exactly.
  scene::AnalyticScene plain = scene::AnalyticScene::objects();
  plain.shadows = false;
  for (auto& shape : plain.shapes) shape.material.pattern = scene::Pattern::solid;
  auto frame_of = [&](int i) {
    const auto cam = orbit_camera(i);
    const auto v = scene::render_analytic(plain, cam, 1);
    Frame f = analytic_frame(cam);
    for (size_t p = 0; p < v.alpha.size(); ++p)
      for (int c = 0; c < 3; ++c) f.image.data[c * v.alpha.size() + p] = v.rgb[p * 3 + c] * v.alpha[p] + (1 - v.alpha[p]);
    return f;
  };
  const Frame s = frame_of(0);
  for (int k : {1, 7}) {
    const Frame t = frame_of(k);
    const Correspondence c = eval::correspond(t.geo, s.geo, space, object_options());
    const double e = eval::masked_rmse(t.image, eval::warp_image(s.image, c, t.image), c.valid);
    INFO("k = " << k << ": plain-material warp RMSE " << e);
    CHECK(e < 0.02);
  }
}

TEST_CASE("a known per-frame flicker raises RMSE by the expected amount") {
  const Frame t = analytic_frame(orbit_camera(1)), s = analytic_frame(orbit_camera(0));
  const Correspondence c = eval::correspond(t.geo, s.geo, RaySpace{false, 1.0f}, object_options());
  const io::Image warped = eval::warp_image(s.image, c, t.image);
  const double e0 = eval::masked_rmse(t.image, warped, c.valid);
  const double m = mean_valid_difference(t.image, warped, c);
  for (float delta : {0.02f, 0.1f, 0.3f}) {
    io::Image brighter = s.image;  // not clamped: the brightness change is exactly delta
    for (float& v : brighter.data) v += delta;
    const double e = eval::masked_rmse(t.image, eval::warp_image(brighter, c, t.image), c.valid);
    // mean((d - delta)^2) = mean(d^2) - 2 delta mean(d) + delta^2
    CHECK(e * e == doctest::Approx(e0 * e0 - 2 * delta * m + double(delta) * delta).epsilon(1e-4));
    CHECK(e > e0);
  }
  // Through the path scorer: odd frames flicker, so every short-range pair differs by delta.
  std::vector<Frame> frames;
  for (int i = 0; i < 9; ++i) frames.push_back(analytic_frame(orbit_camera(i)));
  std::vector<FrameGeometry> geos;
  std::vector<io::Image> clean, flicker;
  for (size_t i = 0; i < frames.size(); ++i) {
    geos.push_back(frames[i].geo);
    clean.push_back(frames[i].image);
    flicker.push_back(frames[i].image);
    if (i % 2) for (float& v : flicker.back().data) v += 0.2f;
  }
  eval::ConsistencyOptions opt;
  opt.warp = object_options();
  const auto warps = eval::path_warps(geos, RaySpace{false, 1.0f}, opt);
  CHECK(warps.short_range.warps.size() == 8);
  CHECK(warps.long_range.warps.size() == 2);
  const auto a = eval::score_frames(clean, warps, nullptr), b = eval::score_frames(flicker, warps, nullptr);
  CHECK(a.short_range.rmse < 0.1);
  CHECK(b.short_range.rmse > 0.2 - a.short_range.rmse);
  CHECK(b.short_range.rmse < 0.2 + a.short_range.rmse);
  CHECK(b.short_range.rmse > 1.5 * a.short_range.rmse);
  CHECK(std::isnan(a.short_range.lpips));  // not measured
  // A distance given as LPIPS is called once per pair with the validity mask.
  int calls = 0;
  eval::MaskedDistance fake = [&](const io::Image& x, const io::Image& y, const std::vector<float>& mask) {
    ++calls;
    CHECK(mask.size() == size_t(x.width) * x.height);
    return eval::masked_rmse(x, y, std::vector<uint8_t>(mask.begin(), mask.end()));
  };
  const auto c2 = eval::score_frames(flicker, warps, &fake);
  CHECK(calls == 10);
  CHECK(c2.short_range.lpips == doctest::Approx(b.short_range.rmse));
  const auto j = c2.to_json();
  CHECK(j["short"]["pairs"].size() == 8);
  CHECK(j["long"]["k"] == 7);
}

namespace {

// A hand-computable path: 4x4 frames of one plane z = -40, seen by cameras that differ by a translation
// only (no rotation; fx = fy = 40 = the plane's distance, so a camera moved by (o, -o, 0) sees the plane
// shifted by exactly o pixels right and down). Pixel (x, y) of frame i shows the plane's point at global
// position (x + o_i, y + o_i), where a linear texture T = 0.1 + 0.02 u + 0.01 v is painted, and the whole
// frame is brightened by b_i per channel. Bilinear sampling reproduces a linear texture exactly, so on every
// valid pixel the warped difference is b_t - b_s, whatever the sample position.
constexpr int kHand = 4;
constexpr double kHandOffsets[4] = {0.0, 0.25, 1.75, 12.5};
constexpr double kHandBrightness[4][3] = {{0, 0, 0}, {0.1, 0.2, 0.2}, {0.4, 0.5, 0.5}, {0, 0, 0}};

FrameGeometry hand_geometry(int i) {
  FrameGeometry f;
  f.camera.fx = f.camera.fy = 40;
  f.camera.cx = f.camera.cy = 0.5f * kHand;
  f.camera.width = f.camera.height = kHand;
  f.camera.c2w[0][3] = float(kHandOffsets[i]);
  f.camera.c2w[1][3] = float(-kHandOffsets[i]);
  for (int y = 0; y < kHand; ++y)
    for (int x = 0; x < kHand; ++x) {
      const double u = (x + 0.5 - f.camera.cx) / 40.0, v = (y + 0.5 - f.camera.cy) / 40.0;
      f.depth.push_back(float(40.0 * std::sqrt(1 + u * u + v * v)));  // distance along the unit ray
      f.opacity.push_back(1.0f);
    }
  return f;
}

io::Image hand_image(int i) {
  io::Image im{kHand, kHand, std::vector<float>(size_t(3) * kHand * kHand)};
  for (int c = 0; c < 3; ++c)
    for (int y = 0; y < kHand; ++y)
      for (int x = 0; x < kHand; ++x)
        im.at(c, y, x) = float(0.1 + 0.02 * (x + kHandOffsets[i]) + 0.01 * (y + kHandOffsets[i]) + kHandBrightness[i][c]);
  return im;
}

// The hand-computed 4-frame path and its warps (short range 1, long range 2).
struct HandPath {
  std::vector<FrameGeometry> geos;
  std::vector<io::Image> frames;
  eval::PathWarps warps;
};

HandPath hand_path() {
  HandPath p;
  for (int i = 0; i < 4; ++i) p.geos.push_back(hand_geometry(i)), p.frames.push_back(hand_image(i));
  eval::ConsistencyOptions opt;
  opt.short_range = 1;
  opt.long_range = 2;
  p.warps = eval::path_warps(p.geos, RaySpace{false, 1.0f}, opt);
  return p;
}

}  // namespace

TEST_CASE("hand-computed path: per-pair RMSE, the range's mean over pairs, and a pair with no valid pixel") {
  const HandPath path = hand_path();
  const std::vector<io::Image>& frames = path.frames;
  const auto& warps = path.warps;
  int lpips_calls = 0;
  // A stand-in for LPIPS that returns the fraction of the frame the mask keeps: 9/16, 4/16 and 4/16 below.
  eval::MaskedDistance kept = [&](const io::Image&, const io::Image&, const std::vector<float>& mask) {
    ++lpips_calls;
    double sum = 0;
    for (float m : mask) sum += m;
    return sum / double(mask.size());
  };
  const eval::ConsistencyScore score = eval::score_frames(frames, warps, &kept);
  const eval::RangeScore& sr = score.short_range;
  const eval::RangeScore& lr = score.long_range;
  REQUIRE(sr.pairs.size() == 3);
  REQUIRE(lr.pairs.size() == 2);

  // Landing positions x + 0.5 + (o_t - o_s), kept inside the pixel centres [0.5, 3.5] in x and in y:
  //   1 -> 0: shift 0.25, x, y in 0..2: 9 pixels;   2 -> 1: shift 1.5, x, y in 0..1: 4 pixels;
  //   3 -> 2: shift 10.75: none (all 16 off the image);
  //   2 -> 0: shift 1.75, x, y in 0..1: 4 pixels;   3 -> 1: shift 12.25: none.
  const int64_t valid[3] = {9, 4, 0}, valid_long[2] = {4, 0};
  for (int p = 0; p < 3; ++p) {
    CAPTURE(p);
    CHECK(sr.pairs[size_t(p)].t == p + 1);
    CHECK(sr.pairs[size_t(p)].s == p);
    CHECK(sr.pairs[size_t(p)].stats.valid == valid[p]);
    CHECK(sr.pairs[size_t(p)].stats.off_image == 16 - valid[p]);
  }
  for (int p = 0; p < 2; ++p) CHECK(lr.pairs[size_t(p)].stats.valid == valid_long[p]);

  // Per pair, RMSE = sqrt(mean over the 3 channels of (b_t - b_s)^2), by hand:
  //   1 -> 0: (0.1, 0.2, 0.2): sqrt(0.09 / 3) = sqrt(0.03);   2 -> 1: (0.3, 0.3, 0.3): 0.3;
  //   2 -> 0: (0.4, 0.5, 0.5): sqrt(0.66 / 3) = sqrt(0.22).
  const double r10 = 0.17320508075688773, r21 = 0.3, r20 = 0.46904157598234297;
  CHECK(sr.pairs[0].rmse == doctest::Approx(r10).epsilon(1e-5));
  CHECK(sr.pairs[1].rmse == doctest::Approx(r21).epsilon(1e-5));
  CHECK(lr.pairs[0].rmse == doctest::Approx(r20).epsilon(1e-5));
  // The empty pairs: NaN scores of their own, left out of the mean and counted as skipped.
  CHECK(std::isnan(sr.pairs[2].rmse));
  CHECK(std::isnan(sr.pairs[2].lpips));
  CHECK(std::isnan(lr.pairs[1].rmse));
  CHECK(sr.skipped == 1);
  CHECK(lr.skipped == 1);

  // The range's score is the plain mean over the pairs with valid pixels: (sqrt(0.03) + 0.3) / 2 =
  // 0.236603. Pooling the pixels (sqrt((9 x 0.03 + 4 x 0.09) / 13) = 0.220140) or dividing by all three
  // pairs (0.157735) gives other values.
  CHECK(sr.rmse == doctest::Approx(0.23660254037844387).epsilon(1e-5));
  CHECK(lr.rmse == doctest::Approx(r20).epsilon(1e-5));  // one pair with pixels; not r20 / 2
  // LPIPS is averaged the same way, and never called for an empty pair.
  CHECK(lpips_calls == 3);
  CHECK(sr.lpips == doctest::Approx((9.0 / 16 + 4.0 / 16) / 2).epsilon(1e-12));
  CHECK(lr.lpips == doctest::Approx(4.0 / 16).epsilon(1e-12));
  // The valid fraction is the mean over every pair, the empty ones included: 13 / 48 and 4 / 32.
  CHECK(sr.valid_fraction == doctest::Approx(13.0 / 48).epsilon(1e-12));
  CHECK(lr.valid_fraction == doctest::Approx(4.0 / 32).epsilon(1e-12));

  // What `eval consistency --json` writes: the empty pair's scores as null, and the count.
  const auto j = score.to_json();
  CHECK(j["short"]["skipped"] == 1);
  CHECK(j["short"]["pairs"][2]["rmse"].is_null());
  CHECK(j["short"]["pairs"][2]["left_out"]["off_image"] == 16);
  CHECK(double(j["short"]["rmse"]) == doctest::Approx(0.23660254037844387).epsilon(1e-5));
  // Read back (how MPI ranks send scores to rank 0): every number the same, the empty pair's NaN kept.
  const auto back = eval::ConsistencyScore::from_json(nlohmann::json::parse(j.dump()));
  CHECK(back.to_json().dump() == j.dump());
  CHECK(back.short_range.rmse == sr.rmse);
  CHECK(back.long_range.lpips == lr.lpips);
  CHECK(back.short_range.pairs[1].stats.valid == 4);
  CHECK(std::isnan(back.short_range.pairs[2].rmse));
  CHECK(std::isnan(back.short_range.pairs[2].lpips));

  // Without a single valid pair the range has no score (NaN), not 0.
  const std::vector<io::Image> far_apart{frames[0], frames[3], frames[0]};
  eval::ConsistencyOptions one_and_two;
  one_and_two.short_range = 1;
  one_and_two.long_range = 2;
  const auto none = eval::score_frames(
      far_apart, eval::path_warps({path.geos[0], path.geos[3], path.geos[0]}, RaySpace{false, 1.0f}, one_and_two),
      nullptr);
  CHECK(none.short_range.skipped == 2);
  CHECK(std::isnan(none.short_range.rmse));
}

TEST_CASE("NaN or infinite pixels reaching the consistency score or LPIPS are errors naming the pixel") {
  HandPath path = hand_path();
  std::vector<io::Image>& frames = path.frames;
  const auto& warps = path.warps;
  frames[2].at(1, 3, 2) = std::numeric_limits<float>::quiet_NaN();
  testing::expect_error([&] { eval::score_frames(frames, warps, nullptr); },
                        "consistency: frame 2 has a NaN value at pixel 2,3, channel 1");
  frames[2] = hand_image(2);
  frames[3].at(0, 0, 1) = std::numeric_limits<float>::infinity();  // frame 3 takes part in empty pairs only
  testing::expect_error([&] { eval::score_frames(frames, warps, nullptr); },
                        "consistency: frame 3 has an infinite value at pixel 1,0, channel 0");
  const std::vector<uint8_t> all(size_t(kHand) * kHand, 1);
  testing::expect_error([&] { eval::masked_rmse(hand_image(0), frames[3], all); },
                        "masked_rmse: image b has an infinite value at pixel 1,0");

  // LPIPS (AlexNet's weights, from the set-up command), both overloads, before any network runs.
  const eval::Lpips lpips = eval::Lpips::load_default(eval::LpipsNet::Alex);
  const int n = lpips.min_side();
  io::Image ok{n, n, std::vector<float>(size_t(3) * n * n, 0.5f)}, bad = ok;
  bad.at(2, 7, 4) = std::numeric_limits<float>::quiet_NaN();
  const std::vector<float> mask(size_t(n) * n, 1.0f);
  testing::expect_error([&] { lpips.distance(bad, ok); }, "LPIPS: image a has a NaN value at pixel 4,7, channel 2");
  testing::expect_error([&] { lpips.distance(ok, bad, mask); }, "LPIPS: image b has a NaN value at pixel 4,7, channel 2");
  CHECK(lpips.distance(ok, ok, mask) == 0.0);  // the same images are still scored
}

TEST_CASE("masks: background, image borders and occlusion") {
  const Frame t = analytic_frame(orbit_camera(7)), s = analytic_frame(orbit_camera(0));
  const Correspondence c = eval::correspond(t.geo, s.geo, RaySpace{false, 1.0f}, object_options());
  int64_t background = 0;
  for (float a : t.geo.opacity) background += a < 0.5f;
  CHECK(c.stats.background >= background);  // frame t's empty space, plus landings on frame s's
  for (size_t i = 0; i < c.valid.size(); ++i) {
    if (!c.valid[i]) continue;
    CHECK(t.geo.opacity[i] >= 0.5f);
    CHECK(c.x[i] >= 0.5f);
    CHECK(c.x[i] <= kSize - 0.5f);
  }
  CHECK(c.stats.occluded > 0);  // 21 degrees apart, the objects hide parts of each other

  // Borders: frame s zoomed in (a longer focal length) sees only the middle; what frame t sees beyond it
  // lands off frame s's image.
  Frame zoomed = s;
  zoomed.geo.camera.fx = zoomed.geo.camera.fy = s.geo.camera.fx * 3;
  const auto zr = scene::render_analytic(scene::AnalyticScene::objects(), zoomed.geo.camera, 1);
  zoomed.geo.depth = zr.depth;
  zoomed.geo.opacity = zr.alpha;
  const Correspondence cz = eval::correspond(t.geo, zoomed.geo, RaySpace{false, 1.0f}, object_options());
  CHECK(cz.stats.off_image > c.stats.off_image + kSize * kSize / 10);

  // Occlusion: frame s with an occluder at half the distance over its whole image.
  Frame blocked = s;
  for (float& d : blocked.geo.depth) d = d > 0 ? 0.5f * d : 1.0f;
  std::fill(blocked.geo.opacity.begin(), blocked.geo.opacity.end(), 1.0f);
  const Correspondence co = eval::correspond(t.geo, blocked.geo, RaySpace{false, 1.0f}, object_options());
  CHECK(co.stats.valid == 0);
  CHECK(co.stats.occluded > 0);
  CHECK(std::isnan(eval::masked_rmse(t.image, eval::warp_image(s.image, co, t.image), co.valid)));

  // A looser tolerance never keeps fewer pixels.
  eval::WarpOptions loose = object_options();
  loose.depth_tolerance = 0.2f;
  CHECK(eval::correspond(t.geo, s.geo, RaySpace{false, 1.0f}, loose).stats.valid >= c.stats.valid);
}

TEST_CASE("depth 0, infinite depths and the NDC far end are never warped; a NaN depth or opacity is an error") {
  Frame t = analytic_frame(orbit_camera(1));
  const Frame s = analytic_frame(orbit_camera(0));
  eval::WarpOptions opt;  // no background masking: only the depth decides
  const float inf = std::numeric_limits<float>::infinity(), nan = std::numeric_limits<float>::quiet_NaN();
  std::fill(t.geo.opacity.begin(), t.geo.opacity.end(), 1.0f);
  for (size_t i = 0; i < t.geo.depth.size(); ++i) t.geo.depth[i] = i % 2 == 0 ? 0.0f : inf;
  const Correspondence c = eval::correspond(t.geo, s.geo, RaySpace{false, 1.0f}, opt);
  CHECK(c.stats.valid == 0);
  CHECK(c.stats.no_depth == int64_t(kSize) * kSize);
  // NaN is no renderer's empty ray (those are 0): a failed render, refused in either frame, naming the pixel.
  Frame broken = analytic_frame(orbit_camera(1));
  broken.geo.depth[size_t(5) * kSize + 9] = nan;
  testing::expect_error([&] { eval::correspond(broken.geo, s.geo, RaySpace{false, 1.0f}, opt); },
                        "warp: frame t has a NaN depth at pixel 9,5");
  testing::expect_error([&] { eval::correspond(s.geo, broken.geo, RaySpace{false, 1.0f}, opt); },
                        "warp: frame s has a NaN depth at pixel 9,5");
  broken = analytic_frame(orbit_camera(1));
  broken.geo.opacity[3] = nan;
  testing::expect_error([&] { eval::correspond(broken.geo, s.geo, RaySpace{false, 1.0f}, object_options()); },
                        "warp: frame t has a NaN opacity at pixel 3,0");
  std::vector<FrameGeometry> path(8, s.geo);
  path[4] = broken.geo;
  testing::expect_error([&] { eval::path_warps(path, RaySpace{false, 1.0f}, {}); }, "NaN opacity at pixel 3,0");

  // NDC: depth 0 is the near plane (a real point); t >= ndc_far is at infinity.
  scene::Camera fwd;
  fwd.fx = fwd.fy = 50;
  fwd.cx = fwd.cy = 16;
  fwd.width = fwd.height = 32;
  FrameGeometry a{fwd, std::vector<float>(32 * 32, 0.9995f), std::vector<float>(32 * 32, 1.0f)};
  scene::Camera moved = fwd;
  moved.c2w[0][3] = 0.01f;
  FrameGeometry b{moved, std::vector<float>(32 * 32, 0.5f), std::vector<float>(32 * 32, 1.0f)};
  const Correspondence far = eval::correspond(a, b, RaySpace{true, 1.0f}, opt);
  CHECK(far.stats.no_depth == 32 * 32);
  a.depth.assign(32 * 32, 0.5f);  // a plane: every pixel moves the same way, and stays in view mostly
  const Correspondence plane = eval::correspond(a, b, RaySpace{true, 1.0f}, opt);
  CHECK(plane.stats.valid > 32 * 32 / 2);
  CHECK(plane.stats.valid + plane.stats.off_image == 32 * 32);

  // Mismatched sizes are refused, naming what is wrong.
  FrameGeometry bad = a;
  bad.depth.resize(10);
  testing::expect_error([&] { eval::correspond(bad, b, RaySpace{true, 1.0f}, opt); }, "depth and opacity");
  std::vector<FrameGeometry> few(5, a);
  testing::expect_error([&] { eval::path_warps(few, RaySpace{true, 1.0f}, {}); }, "long range of 7");
}

TEST_CASE("a background shell is the surface of the pixels the box leaves to it") {
  const RaySpace world{false, 1.0f};
  const double R = 3.0;
  // The exit of a camera's ray through (px, py) from the sphere |X| = R, solved here on its own.
  const auto exit_point = [&](const scene::Camera& cam, double px, double py) {
    const auto P = eval::world_point(cam, px, py, 1.0, world);
    const std::array<double, 3> o{cam.c2w[0][3], cam.c2w[1][3], cam.c2w[2][3]};
    std::array<double, 3> d{P[0] - o[0], P[1] - o[1], P[2] - o[2]};
    double a = 0, b = 0, c = -R * R;
    for (int k = 0; k < 3; ++k) a += d[k] * d[k], b += o[k] * d[k], c += o[k] * o[k];
    const double t = (-b + std::sqrt(b * b - a * c)) / a;
    return std::array<double, 3>{o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]};
  };
  const auto frame = [&](int i) {
    FrameGeometry f;
    f.camera = orbit_camera(i, kSize, 1.0);  // inside the sphere, ~1 from the centre
    f.depth.assign(size_t(kSize) * kSize, 0.0f);
    f.opacity.assign(size_t(kSize) * kSize, 0.0f);
    return f;
  };
  FrameGeometry f = frame(0);
  const size_t held = size_t(kSize / 2) * kSize + kSize / 2, faint = 5;
  f.opacity[held] = 0.8f, f.depth[held] = 0.7f;  // the box holds this pixel: its surface stays
  f.opacity[faint] = 0.49f, f.depth[faint] = 0.9f;  // mostly the shell's colour: the shell is its surface
  eval::add_shell_surface(f, float(R));
  CHECK(f.opacity[held] == 0.8f);
  CHECK(f.depth[held] == 0.7f);
  for (int y = 0; y < kSize; ++y)
    for (int x = 0; x < kSize; ++x) {
      const size_t i = size_t(y) * kSize + x;
      if (i == held) continue;
      REQUIRE(f.opacity[i] == 1.0f);
      const auto X = eval::world_point(f.camera, x + 0.5, y + 0.5, f.depth[i], world);
      CHECK(std::sqrt(X[0] * X[0] + X[1] * X[1] + X[2] * X[2]) == doctest::Approx(R).epsilon(1e-5));
    }
  // Two frames of nothing but the shell: every valid correspondence joins the two cameras' views of one
  // point of the sphere.
  FrameGeometry t = frame(4), s = frame(0);
  eval::add_shell_surface(t, float(R));
  eval::add_shell_surface(s, float(R));
  const Correspondence c = eval::correspond(t, s, world, {});
  CHECK(c.stats.valid_fraction() > 0.5);
  double worst = 0;
  for (int y = 0; y < kSize; ++y)
    for (int x = 0; x < kSize; ++x) {
      const size_t i = size_t(y) * kSize + x;
      if (!c.valid[i]) continue;
      const auto a = exit_point(t.camera, x + 0.5, y + 0.5), b = exit_point(s.camera, c.x[i], c.y[i]);
      worst = std::max(worst, std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                                        (a[2] - b[2]) * (a[2] - b[2])));
    }
  CHECK(worst < 1e-4 * R);
  // A camera outside the sphere sees no exit ahead: the frame is left as it was; a radius must be > 0.
  FrameGeometry outside = frame(0);
  eval::add_shell_surface(outside, 0.5f);
  CHECK(outside.opacity == frame(0).opacity);
  CHECK(outside.depth == frame(0).depth);
  testing::expect_error([&] { eval::add_shell_surface(outside, 0.0f); }, "radius must be > 0");
}

TEST_CASE("the geometry renderer: opacity and depth of a trained density grid without its appearance") {
  const auto& scene = testing::small_scene();
  const auto& geo = testing::small_geometry();
  const scene::Camera cam = scene.test.front().camera;
  const auto v = model::render_geometry(geo, scene, cam, 512);
  REQUIRE(v.acc.size() == size_t(cam.width) * cam.height);
  CHECK(testing::all_finite(v.acc));
  CHECK(testing::all_finite(v.depth));
  int covered = 0;
  for (size_t i = 0; i < v.acc.size(); ++i) {
    CHECK(v.acc[i] >= 0.0f);
    CHECK(v.acc[i] <= 1.0001f);
    CHECK(v.value[i] <= v.acc[i] + 1e-5f);  // kept opacity <= opacity
    if (v.acc[i] > 0.5f) {
      ++covered;
      CHECK(v.depth[i] > scene.near);
      CHECK(v.depth[i] < scene.far);
    }
  }
  CHECK(covered > 0);
  // Chunking (asked for, or bounded by the samples a call may produce) changes nothing.
  const auto small = model::render_geometry(geo, scene, cam, 97);
  const auto huge = model::render_geometry(geo, scene, cam, 1 << 30);
  CHECK(small.acc == v.acc);
  CHECK(huge.depth == v.depth);
}

TEST_CASE("the RGB floor's render gives the table its geometry: one march, the same depth, opacity and warps") {
  const auto& scene = testing::small_scene();
  auto cfg = train::default_density_config(scene);
  cfg.model.density_rank = {8, 8, 8};
  cfg.model.app_rank = {8, 8, 8};
  cfg.model.hidden = 32;
  cfg.model.act = field::DensityActivation::Relu;
  model::DensityModel m = model::DensityModel::create(scene, cfg.model, testing::small_geometry().res(), 7);
  m.geo = testing::small_geometry();  // the trained density and its mask; the appearance stays untrained
  eval::PathOptions p;
  p.frames = 8;
  p.chunk = 512;
  const auto cams = eval::path_cameras(scene, p.frames, p.path_frames, p.size);
  std::vector<FrameGeometry> from_rgb;
  const auto rgb = eval::rgb_frames(m, scene, cams, p.chunk, &from_rgb);
  const auto alone = eval::render_path_geometry(m.geo, scene, cams, p.chunk);
  REQUIRE(rgb.size() == cams.size());
  REQUIRE(from_rgb.size() == alone.size());
  int covered = 0;
  for (size_t i = 0; i < alone.size(); ++i) {
    CHECK(from_rgb[i].depth == alone[i].depth);
    CHECK(from_rgb[i].opacity == alone[i].opacity);
    for (float a : alone[i].opacity) covered += a > 0.5f;
  }
  CHECK(covered > 0);
  const eval::PathSetup a = eval::path_setup(m.geo, scene, p);
  const eval::PathSetup b = eval::path_setup(from_rgb, m.geo, scene, p);
  REQUIRE(a.warps.short_range.warps.size() == b.warps.short_range.warps.size());
  REQUIRE(a.warps.long_range.warps.size() == b.warps.long_range.warps.size());
  for (size_t i = 0; i < a.warps.short_range.warps.size(); ++i) {
    CHECK(a.warps.short_range.warps[i].valid == b.warps.short_range.warps[i].valid);
    CHECK(a.warps.short_range.warps[i].x == b.warps.short_range.warps[i].x);
  }
  CHECK(a.warps.long_range.warps.back().valid == b.warps.long_range.warps.back().valid);
  // With a background shell about every camera, the pixels the box leaves are warped by the shell: more
  // of each frame is scored.
  model::Geometry shelled = m.geo;
  shelled.has_background = false;
  shelled.shell.radius = 100.0f;
  const eval::PathSetup w = eval::path_setup(from_rgb, shelled, scene, p);
  int64_t plain_valid = 0, shell_valid = 0;
  for (size_t i = 0; i < w.warps.long_range.warps.size(); ++i) {
    plain_valid += a.warps.long_range.warps[i].stats.valid;
    shell_valid += w.warps.long_range.warps[i].stats.valid;
  }
  CHECK(shell_valid > plain_valid);
  // Frames of another path are refused, naming the counts.
  from_rgb.pop_back();
  testing::expect_error([&] { eval::path_setup(from_rgb, m.geo, scene, p); }, "7 rendered frames for a path of 8");
}
