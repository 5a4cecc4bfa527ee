// The style stage's multi-view term (lib/train/multiview_term.hpp): the loss against a double-precision
// reference and its gradients against central differences; two true views of a generated scene warped by
// their true depth score near zero and a known flicker scores what it should; the patch geometry's
// interpolation; the second camera's choice (within the angle, none beyond it, none for an empty patch);
// NaN pictures and size mismatches are errors.
#include <doctest/doctest.h>

#include <cmath>
#include <limits>
#include <random>

#include "lib/train/multiview_term.hpp"
#include "tests/orbit_frames.hpp"
#include "tests/testing.hpp"

using namespace stylerf;
using train::multiview_loss;

namespace {

using testing::analytic_frame;
using testing::object_options;
using testing::orbit_camera;

io::Image random_image(int w, int h, std::mt19937& rng) {
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  io::Image img{w, h, std::vector<float>(size_t(3) * w * h)};
  for (float& v : img.data) v = u(rng);
  return img;
}

// A correspondence of a w x h frame into a ws x hs one: random landing positions inside the pixel centres
// (borders included), about a third of the pixels not valid.
eval::Correspondence random_correspondence(int w, int h, int ws, int hs, std::mt19937& rng) {
  eval::Correspondence c;
  c.width = w;
  c.height = h;
  std::uniform_real_distribution<float> ux(0.5f, ws - 0.5f), uy(0.5f, hs - 0.5f), coin(0.0f, 1.0f);
  for (int i = 0; i < w * h; ++i) {
    c.x.push_back(i == 0 ? ws - 0.5f : ux(rng));  // the last pixel centre: the bilinear sample's edge
    c.y.push_back(i == 0 ? hs - 0.5f : uy(rng));
    c.valid.push_back(i == 0 || coin(rng) > 0.33f ? 1 : 0);
  }
  return c;
}

// The loss in double, written out on its own: weight x mean over valid pixels and channels of the squared
// difference to the bilinear sample.
double reference_loss(const io::Image& a, const io::Image& b, const eval::Correspondence& c, double weight) {
  double sum = 0;
  int64_t n = 0;
  for (int y = 0; y < c.height; ++y)
    for (int x = 0; x < c.width; ++x) {
      const size_t i = size_t(y) * c.width + x;
      if (!c.valid[i]) continue;
      const double u = std::min(std::max(double(c.x[i]) - 0.5, 0.0), double(b.width - 1));
      const double v = std::min(std::max(double(c.y[i]) - 0.5, 0.0), double(b.height - 1));
      const int x0 = int(std::floor(u)), y0 = int(std::floor(v));
      const int x1 = std::min(x0 + 1, b.width - 1), y1 = std::min(y0 + 1, b.height - 1);
      const double ax = u - x0, ay = v - y0;
      for (int ch = 0; ch < 3; ++ch) {
        const double s = (1 - ay) * ((1 - ax) * b.at(ch, y0, x0) + ax * b.at(ch, y0, x1)) +
                         ay * ((1 - ax) * b.at(ch, y1, x0) + ax * b.at(ch, y1, x1));
        const double r = a.at(ch, y, x) - s;
        sum += r * r;
      }
      ++n;
    }
  return n ? weight * sum / (3.0 * double(n)) : 0.0;
}

}  // namespace

TEST_CASE("multi-view loss: the double reference, and both gradients against central differences") {
  std::mt19937 rng(5);
  const io::Image a = random_image(9, 7, rng), b = random_image(6, 5, rng);
  const eval::Correspondence c = random_correspondence(9, 7, 6, 5, rng);
  const float weight = 3.5f;
  const train::MultiviewLoss l = multiview_loss(a, b, c, weight);
  int64_t valid = 0;
  for (uint8_t v : c.valid) valid += v;
  CHECK(l.pixels == valid);
  CHECK(l.value == doctest::Approx(reference_loss(a, b, c, weight)).epsilon(1e-9));
  CHECK(l.value > 0);
  // The loss is quadratic in the pictures: a central difference is exact up to rounding.
  auto check_gradient = [&](bool first) {
    const io::Image& grad = first ? l.d_first : l.d_second;
    const io::Image& picture = first ? a : b;
    REQUIRE(grad.data.size() == picture.data.size());
    double worst = 0;
    for (size_t k = 0; k < picture.data.size(); ++k) {
      io::Image plus = picture, minus = picture;
      const float h = 1e-2f;
      plus.data[k] += h;
      minus.data[k] -= h;
      const double fd = first ? (reference_loss(plus, b, c, weight) - reference_loss(minus, b, c, weight)) / (2.0 * h)
                              : (reference_loss(a, plus, c, weight) - reference_loss(a, minus, c, weight)) / (2.0 * h);
      worst = std::max(worst, std::abs(fd - double(grad.data[k])));
    }
    INFO((first ? "d first" : "d second") << ": worst difference " << worst);
    CHECK(worst < 1e-5);
  };
  check_gradient(true);
  check_gradient(false);
  // Pixels that are not valid get no gradient.
  for (size_t i = 0; i < c.valid.size(); ++i)
    if (!c.valid[i])
      for (int ch = 0; ch < 3; ++ch) CHECK(l.d_first.data[ch * c.valid.size() + i] == 0.0f);
}

TEST_CASE("multi-view loss: no valid pixel scores 0 with zero gradients; weight 0 scores 0") {
  std::mt19937 rng(6);
  const io::Image a = random_image(5, 4, rng), b = random_image(5, 4, rng);
  eval::Correspondence c = random_correspondence(5, 4, 5, 4, rng);
  std::fill(c.valid.begin(), c.valid.end(), uint8_t(0));
  const train::MultiviewLoss none = multiview_loss(a, b, c, 10.0f);
  CHECK(none.value == 0.0);
  CHECK(none.pixels == 0);
  for (float g : none.d_first.data) CHECK(g == 0.0f);
  for (float g : none.d_second.data) CHECK(g == 0.0f);
  const eval::Correspondence all = random_correspondence(5, 4, 5, 4, rng);
  CHECK(multiview_loss(a, b, all, 0.0f).value == 0.0);
}

TEST_CASE("multi-view loss: two true views warped by their true depth agree; a known flicker scores its square") {
  const eval::RaySpace space{false, 1.0f};
  for (int k : {2, 8}) {
    const testing::AnalyticFrame t = analytic_frame(orbit_camera(k)), s = analytic_frame(orbit_camera(0));
    const eval::Correspondence c = eval::correspond(t.geo, s.geo, space, object_options());
    REQUIRE(c.stats.valid > testing::kOrbitSize * testing::kOrbitSize / 10);
    const double agree = multiview_loss(t.image, s.image, c, 1.0f).value;
    INFO("k = " << k << ": mean squared difference " << agree);
    CHECK(agree < 1e-2);  // the bilinear resampling of the checker textures (their edges) alone
    // Every pixel of the second view 0.2 brighter: the mean squared difference grows by about 0.04.
    io::Image bright = s.image;
    for (float& v : bright.data) v += 0.2f;
    const double flicker = multiview_loss(t.image, bright, c, 1.0f).value;
    CHECK(flicker == doctest::Approx(agree + 0.04).epsilon(0.15));
  }
}

TEST_CASE("multi-view loss: NaN pictures and mismatched sizes are errors") {
  std::mt19937 rng(7);
  const io::Image a = random_image(4, 4, rng), b = random_image(4, 4, rng);
  const eval::Correspondence c = random_correspondence(4, 4, 4, 4, rng);
  io::Image bad = b;
  bad.data[5] = std::numeric_limits<float>::quiet_NaN();
  testing::expect_error([&] { multiview_loss(a, bad, c, 1.0f); }, "second picture holds a NaN");
  bad = a;
  bad.data[2] = std::numeric_limits<float>::infinity();
  testing::expect_error([&] { multiview_loss(bad, b, c, 1.0f); }, "first picture holds a NaN");
  const io::Image small = random_image(3, 4, rng);
  testing::expect_error([&] { multiview_loss(small, b, c, 1.0f); }, "with a correspondence of 4x4");
}

TEST_CASE("patch geometry: depth and opacity bilinear between the block centres, the depth divided by the opacity") {
  const int mw = 4, mh = 3, stride = 4;
  std::vector<float> dsum(size_t(mw) * mh), acc(size_t(mw) * mh, 1.0f);
  for (int j = 0; j < mh; ++j)
    for (int i = 0; i < mw; ++i) dsum[size_t(j) * mw + i] = 2.0f + 0.5f * i + 0.25f * j;  // linear
  const scene::Camera cam = train::patch_camera(orbit_camera(0, 64), 8, 12, mw * stride, mh * stride);
  CHECK(cam.width == 16);
  CHECK(cam.height == 12);
  CHECK(cam.cx == doctest::Approx(32.0f - 8.0f));
  CHECK(cam.cy == doctest::Approx(32.0f - 12.0f));
  const eval::FrameGeometry g = train::patch_geometry(cam, mw, mh, stride, dsum, acc);
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      // Between the block centres the interpolation of a linear map is the map; beyond them it is clamped.
      const double u = std::min(std::max((x + 0.5) / stride - 0.5, 0.0), double(mw - 1));
      const double v = std::min(std::max((y + 0.5) / stride - 0.5, 0.0), double(mh - 1));
      CHECK(g.depth[size_t(y) * cam.width + x] == doctest::Approx(2.0 + 0.5 * u + 0.25 * v).epsilon(1e-6));
      CHECK(g.opacity[size_t(y) * cam.width + x] == doctest::Approx(1.0));
    }
  // Half the blocks empty (opacity 0, depth sum 0): a pixel between a surface and empty space keeps the
  // surface's depth at a partial opacity; a pixel among empty blocks has depth 0.
  std::vector<float> dsum2(size_t(mw) * mh, 0.0f), acc2(size_t(mw) * mh, 0.0f);
  for (int j = 0; j < mh; ++j) dsum2[size_t(j) * mw] = 3.0f, acc2[size_t(j) * mw] = 1.0f;
  const eval::FrameGeometry h = train::patch_geometry(cam, mw, mh, stride, dsum2, acc2);
  CHECK(h.depth[4] == doctest::Approx(3.0));  // x = 4: between block 0 (surface) and block 1 (empty)
  CHECK(h.opacity[4] == doctest::Approx(1.0 - (4.5 / 4 - 0.5)));
  CHECK(h.depth[15] == 0.0f);
  CHECK(h.opacity[15] == 0.0f);
  testing::expect_error([&] { train::patch_geometry(cam, mw, mh, stride, std::vector<float>(3), acc); },
                        "needs 12 depths");
}

TEST_CASE("the second camera: a training view within the angle that sees the patch's surface, centred on it") {
  scene::Scene sc;
  for (int i = 0; i < 120; i += 10) sc.train.push_back({orbit_camera(i), "", {}, {}});  // 30 degrees apart
  const testing::AnalyticFrame first = analytic_frame(sc.train[0].camera);
  const eval::RaySpace space{false, 1.0f};
  std::mt19937_64 draw(3);
  int seen[12] = {};
  for (int trial = 0; trial < 40; ++trial) {
    const train::SecondPatch sp = train::pick_second_patch(sc, first.geo, 0, 32, 32, 35.0f, space, draw);
    REQUIRE(sp.view >= 0);
    ++seen[sp.view];
    CHECK(sp.x0 % 4 == 0);
    CHECK(sp.y0 % 4 == 0);
    CHECK(sp.x0 >= 0);
    CHECK(sp.x0 <= testing::kOrbitSize - 32);
    CHECK(sp.y0 >= 0);
    CHECK(sp.y0 <= testing::kOrbitSize - 32);
  }
  // Only the neighbours 30 degrees either side qualify, and the choice between them is random.
  CHECK(seen[1] > 0);
  CHECK(seen[11] > 0);
  CHECK(seen[1] + seen[11] == 40);
  // Nothing within 20 degrees; an empty first patch has no surface to share.
  CHECK(train::pick_second_patch(sc, first.geo, 0, 32, 32, 20.0f, space, draw).view == -1);
  eval::FrameGeometry empty = first.geo;
  std::fill(empty.opacity.begin(), empty.opacity.end(), 0.0f);
  CHECK(train::pick_second_patch(sc, empty, 0, 32, 32, 90.0f, space, draw).view == -1);
}
