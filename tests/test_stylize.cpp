// Zero-shot use of a style model (lib/model/region.hpp, lib/style/style_encoder.hpp, StyleModel's camera
// calls):
//  - the region indicator kernel against a double-precision reference (box, sphere, depth slab; plain and
//    NDC ray spaces), including the NDC far end (infinitely far points) and the spec parser's errors;
//  - the rendered region mask on a generated scene: the whole box gives 1 wherever anything was kept, an
//    empty region 0; the composed render is the per-pixel blend m yA + (1 - m) yB of the two styles' DST
//    maps, and equals the single-style render when the mask is all 1;
//  - style codes: interpolation weights, the memory and disk caches (identical values; a damaged entry is
//    recomputed), different images give different keys;
//  - hard style images: 1x1 grey, 16-bit PNG, CMYK JPEG (tests/data/styles) give finite codes and images;
//    a text file named .png is an error naming the file; a style folder skips it;
//  - background compositing: opacity 0 gives the scene's colour, opacity 1 leaves the image;
//  - supersampled content: the mean of the n x n sub-ray renders (c, opacities, depth, region mask), one
//    ray per block centre at n = 1, and out-of-range n refused; the quincunx: (4 x the centre + the four
//    corner rays, rendered on their own) / 8, unrefined blocks their centre ray, the names parsed; refined only where blocks_to_refine finds
//    an edge (a step, an opacity change; not a flat map or a linear ramp), the centre ray elsewhere;
//  - a path's content rendered once and shared by two styles (eval table) gives each style the very
//    frames it gets rendered alone.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <random>

#include "host/error.hpp"
#include "lib/eval/path_frames.hpp"
#include "lib/io/image.hpp"
#include "lib/model/block_refine.hpp"
#include "lib/model/opacity_head.hpp"
#include "lib/model/style_model.hpp"
#include "lib/scene/rays.hpp"
#include "lib/style/style_encoder.hpp"
#include "lib/style/style_image.hpp"
#include "tests/small_scene.hpp"
#include "tests/testing.hpp"

using namespace stylerf;
using host::Tensor;
namespace fs = std::filesystem;

namespace {

std::string fixture(const std::string& name) { return std::string(STYLERF_TEST_FIXTURES) + "/styles/" + name; }

// Random normalised positions, a few exactly on the NDC far end (pos z = 1 with the box's hi z = 1).
std::vector<float> random_positions(int n, uint64_t seed) {
  std::vector<float> p = testing::random_uniform(size_t(3) * n, seed, -1.1f, 1.1f);
  for (int i = 0; i < n; i += 17) p[size_t(3 * i + 2)] = 1.0f;
  return p;
}

// Counts disagreements with the double reference, ignoring points within 1e-4 of the boundary (float
// rounding of the position may fall either side there).
int mismatches(const std::vector<float>& pos, const std::vector<float>& got, const model::Region& r,
               const model::RegionSpace& space) {
  int bad = 0;
  for (size_t i = 0; i < got.size(); ++i) {
    const std::array<double, 3> p{pos[3 * i], pos[3 * i + 1], pos[3 * i + 2]};
    const bool want = space.contains(r, p);
    bool near_edge = false;
    for (int a = 0; a < 3 && !near_edge; ++a)
      for (double e : {-1e-4, 1e-4}) {
        auto q = p;
        q[a] += e;
        if (space.contains(r, q) != want) near_edge = true;
      }
    if (!near_edge && (got[i] == 1.0f) != want) ++bad;
    if (got[i] != 0.0f && got[i] != 1.0f) ++bad;
  }
  return bad;
}

// The largest |got - want| over the largest |want| (1e9 when the sizes differ).
double worst_rel(const std::vector<float>& got, const std::vector<double>& want) {
  double scale = 1e-12, worst = 0;
  for (double v : want) scale = std::max(scale, std::abs(v));
  for (size_t i = 0; i < got.size(); ++i) worst = testing::max_or_nan(worst, std::abs(got[i] - want[i]));
  return got.size() == want.size() ? worst / scale : 1e9;
}

model::StyleModel small_style_model(bool content_skip = false) {
  model::FeatureFieldConfig fc;
  fc.rank = {8, 8, 8};
  model::StyleModel m = model::StyleModel::create(
      model::FeatureModel::create(testing::small_geometry(), fc, model::DecoderProfile::Fast, 3),
      style::SictMode::VolumeAdaptive, true, 5, model::StyleDecoderKind::Stage2, content_skip);
  if (content_skip) m.skip.gain.value.upload(testing::random_uniform(256, 8, 0.5f, 1.5f));
  m.sict.running_mean.value = Tensor::from_host(testing::random_normal(256, 6, 0.05f), {256});
  m.sict.running_var.value = Tensor::from_host(testing::random_uniform(256, 7, 0.01f, 0.05f), {256});
  return m;
}

style::StyleCode random_code(uint64_t seed) {
  style::StyleCode c;
  c.mean = Tensor::from_host(testing::random_normal(256, seed, 0.5f), {256});
  c.std = Tensor::from_host(testing::random_uniform(256, seed + 1, 0.1f, 1.0f), {256});
  c.T = Tensor::from_host(testing::random_normal(32 * 32, seed + 2, 0.3f), {32, 32});
  return c;
}

}  // namespace

TEST_CASE("region indicator matches the double reference in plain and NDC ray spaces") {
  const int n = 20000;
  const auto pos = random_positions(n, 11);
  const Tensor tpos = Tensor::from_host(pos, {n, 3});
  model::RegionSpace plain;
  plain.lo = {-1.5f, -1.0f, -0.5f};
  plain.hi = {1.5f, 1.0f, 1.0f};
  model::RegionSpace ndc = plain;
  ndc.ndc = true;
  ndc.lo = {-1.2f, -1.1f, -1.0f};
  ndc.hi = {1.2f, 1.1f, 1.0f};
  ndc.sx = 0.6f;
  ndc.sy = 0.45f;
  ndc.near = 1.0f;
  std::vector<scene::Camera> path(3);
  for (int i = 0; i < 3; ++i) path[size_t(i)].c2w[0][3] = 0.1f * i;  // looking down -z
  for (const auto& spec : {"box:-0.5,-0.4,-0.3,0.6,0.5,0.4", "sphere:0.2,-0.1,0.1,0.7", "depth:0.5,2.5",
                           "depth:0.2,inf"}) {
    const model::Region r = model::Region::parse(spec, path);
    const std::string name = spec;
    CAPTURE(name);
    const auto got = model::region_indicator(tpos, r, plain).to_host();
    CHECK(mismatches(pos, got, r, plain) == 0);
    int inside = 0;
    for (float v : got) inside += v == 1.0f;
    CHECK(inside > 100);  // the test exercises both answers
    CHECK(inside < n - 100);
    // NDC: world depths from 0.5 (the near plane) to infinity.
    const auto got_ndc = model::region_indicator(tpos, model::Region::parse(spec, path), ndc).to_host();
    CHECK(mismatches(pos, got_ndc, r, ndc) == 0);
  }
  // Infinitely far NDC points (z = 1): in no box or sphere; inside a slab only when it reaches infinity.
  const Tensor far = Tensor::from_host({0.0f, 0.0f, 1.0f, 0.3f, -0.2f, 1.0f}, {2, 3});
  CHECK(model::region_indicator(far, model::Region::parse("box:-9,-9,-1e30,9,9,9", path), ndc).to_host() ==
        std::vector<float>{0, 0});
  CHECK(model::region_indicator(far, model::Region::parse("sphere:0,0,0,1e30", path), ndc).to_host() ==
        std::vector<float>{0, 0});
  CHECK(model::region_indicator(far, model::Region::parse("depth:0,5", path), ndc).to_host() ==
        std::vector<float>{0, 0});
  CHECK(model::region_indicator(far, model::Region::parse("depth:0,inf", path), ndc).to_host() ==
        std::vector<float>{1, 1});
  // An empty batch.
  CHECK(model::region_indicator(Tensor::zeros({0, 3}), model::Region::parse("depth:0,5", path), ndc).numel() == 0);
}

TEST_CASE("region specs: clear errors") {
  const std::vector<scene::Camera> path(2);
  testing::expect_error([&] { model::Region::parse("cube:0,0,0,1", path); }, "unknown kind 'cube'");
  testing::expect_error([&] { model::Region::parse("box:0,0,0,1,1", path); }, "6 numbers");
  testing::expect_error([&] { model::Region::parse("box:0,0,0,1,-1,1", path); }, "lower corner");
  testing::expect_error([&] { model::Region::parse("sphere:0,0,0,0", path); }, "radius");
  testing::expect_error([&] { model::Region::parse("sphere:0,0,x,1", path); }, "'x' is not a number");
  testing::expect_error([&] { model::Region::parse("sphere:0,0,nan,1", path); }, "'nan' is not a number");
  testing::expect_error([&] { model::Region::parse("depth:3,1", path); }, "d0 < d1");
  testing::expect_error([&] { model::Region::parse("depth:1,3", {}); }, "needs a camera path");
  testing::expect_error([&] { model::Region::parse("sphere", path); }, "expected box:");
}

TEST_CASE("region masks and compositional transfer on a generated scene, with and without the content skip") {
 for (const bool content_skip : {false, true}) {
  CAPTURE(content_skip);
  const model::StyleModel m = small_style_model(content_skip);
  const scene::Scene& sc = testing::small_scene();
  const scene::Camera cam = sc.test.empty() ? sc.train[0].camera : sc.test[0].camera;
  const model::RegionSpace space = model::RegionSpace::of(m.features.geo, sc);
  const std::vector<scene::Camera> path{cam};
  const model::RegionHead everything(model::Region::parse("sphere:0,0,0,1e6", path), space);
  const model::RegionHead nothing(model::Region::parse("sphere:1e5,0,0,1", path), space);
  const auto all = m.render_camera_content(sc, cam, 500, &everything);
  const auto none = m.render_camera_content(sc, cam, 500, &nothing);
  const auto kept = all.content.kept_acc.to_host();
  int visible = 0;
  for (size_t i = 0; i < kept.size(); ++i) {
    CHECK(none.region_mask[i] == 0.0f);
    if (kept[i] > 1e-3f) {
      ++visible;
      CHECK(all.region_mask[i] == doctest::Approx(1.0).epsilon(1e-4));
    }
  }
  CHECK(visible > 10);

  // A half-space box: the blend, computed the direct way on the DST maps.
  const auto half = m.render_camera_content(sc, cam, 500, std::make_unique<model::RegionHead>(
      model::Region::parse("box:-1e6,-1e6,-1e6,0,1e6,1e6", path), space).get());
  int partial = 0;
  for (float v : half.region_mask) partial += v > 0.01f && v < 0.99f;
  MESSAGE("rays partly inside the half-space: " << partial);
  const style::StyleCode a = random_code(21), b = random_code(31);
  const auto composed = m.stylize_camera_regions(half, a, b, cam.width, cam.height);
  Tensor ya = m.transform(half.content.c, half.content.kept_acc, a, nullptr);
  const Tensor yb = m.transform(half.content.c, half.content.kept_acc, b, nullptr);
  auto va = ya.to_host();
  const auto vb = yb.to_host();
  for (size_t r = 0; r < half.region_mask.size(); ++r)
    for (int c = 0; c < 256; ++c) {
      const float mm = half.region_mask[r];
      va[r * 256 + c] = mm * va[r * 256 + c] + (1 - mm) * vb[r * 256 + c];
    }
  const auto direct = model::StyleModel::crop_rgb(
      m.decode_rows(Tensor::from_host(va, {int64_t(va.size() / 256), 256}), half.content.acc, half.height, half.width,
                    nullptr, nullptr),
      cam.width, cam.height);
  REQUIRE(direct.size() == composed.size());
  double worst = 0;
  for (size_t i = 0; i < direct.size(); ++i) worst = testing::max_or_nan(worst, double(std::abs(direct[i] - composed[i])));
  CHECK(worst < 1e-4);
  // All inside: the single-style render.
  const auto inside_all = m.stylize_camera_regions(all, a, b, cam.width, cam.height);
  const auto single = m.stylize_camera(all, a, cam.width, cam.height);
  double worst_single = 0;
  for (size_t i = 0; i < single.size(); ++i) {
    // Rays with nothing kept are all "outside"; they carry only the background there, the same either way.
    worst_single = testing::max_or_nan(worst_single, double(std::abs(single[i] - inside_all[i])));
  }
  CHECK(worst_single < 1e-4);
  const auto plain = m.render_camera_content(sc, cam);
  testing::expect_error([&] { m.stylize_camera_regions(plain, a, b, cam.width, cam.height); }, "without a region");
 }
}

TEST_CASE("supersampled camera content is the mean of its sub-ray renders (the content skip's components too)") {
  const model::StyleModel m = small_style_model(true);
  const scene::Scene& sc = testing::small_scene();
  const scene::Camera cam = sc.test.empty() ? sc.train[0].camera : sc.test[0].camera;
  // The reference: render_content on the rays of each sub-position, summed in double.
  auto reference = [&](int n) {
    int w = 0, h = 0;
    model::block_rays(sc, cam, m.stride(), w, h);
    const size_t R = size_t(w) * h;
    std::vector<double> c(R * size_t(m.content_channels()), 0.0), k(R, 0.0), a(R, 0.0), d(R, 0.0);
    for (int sy = 0; sy < n; ++sy)
      for (int sx = 0; sx < n; ++sx) {
        const auto rays = model::block_rays(sc, cam, m.stride(), w, h, (sx + 0.5f) / n, (sy + 0.5f) / n);
        const auto part = m.render_content(Tensor::from_host(rays.origins, {int64_t(R), 3}),
                                           Tensor::from_host(rays.directions, {int64_t(R), 3}), false, 0, nullptr);
        const auto pc = part.c.to_host(), pk = part.kept_acc.to_host(), pa = part.acc.to_host(),
                   pd = part.depth.to_host();
        for (size_t i = 0; i < c.size(); ++i) c[i] += pc[i] / (n * n);
        for (size_t i = 0; i < R; ++i) k[i] += pk[i] / (n * n), a[i] += pa[i] / (n * n), d[i] += pd[i] / (n * n);
      }
    return std::vector<std::vector<double>>{c, k, a, d};
  };
  const model::RegionSpace space = model::RegionSpace::of(m.features.geo, sc);
  const model::RegionHead everything(model::Region::parse("sphere:0,0,0,1e6", {cam}), space);
  for (int n : {1, 2, 3}) {
    CAPTURE(n);
    const auto cc = m.render_camera_content(sc, cam, 333, &everything, n, 0.0f);  // chunks cut across rows (every block)
    const auto ref = reference(n);
    CHECK(worst_rel(cc.content.c.to_host(), ref[0]) < 1e-6);
    CHECK(worst_rel(cc.content.kept_acc.to_host(), ref[1]) < 1e-6);
    CHECK(worst_rel(cc.content.acc.to_host(), ref[2]) < 1e-6);
    CHECK(worst_rel(cc.content.depth.to_host(), ref[3]) < 1e-6);
    // Everything inside the region: 1 wherever anything was kept, whatever the sub-rays' share.
    const auto kept = cc.content.kept_acc.to_host();
    for (size_t i = 0; i < kept.size(); ++i)
      if (kept[i] > 1e-3f) CHECK(cc.region_mask[i] == doctest::Approx(1.0).epsilon(1e-4));
  }
  // Sub-rays see different things: at n = 2 the map is not the centre rays' map (else the test above
  // would pass for a supersampling that ignored its offsets).
  const auto one = m.render_camera_content(sc, cam, 4096, nullptr, 1).content.acc.to_host();
  const auto two = m.render_camera_content(sc, cam, 4096, nullptr, 2, 0.0f).content.acc.to_host();
  double moved = 0;
  for (size_t i = 0; i < one.size(); ++i) moved = std::max(moved, double(std::abs(one[i] - two[i])));
  CHECK(moved > 1e-3);
  testing::expect_error([&] { m.render_camera_content(sc, cam, 4096, nullptr, -2); }, "supersample must be in 1..8");
  testing::expect_error([&] { m.render_camera_content(sc, cam, 4096, nullptr, 0); }, "supersample must be in 1..8");
  testing::expect_error([&] { m.render_camera_content(sc, cam, 4096, nullptr, 9); }, "supersample must be in 1..8");
}

TEST_CASE("quincunx camera content: (4 x the centre ray + the four corner rays) / 8, corners shared") {
  const model::StyleModel m = small_style_model();
  const scene::Scene& sc = testing::small_scene();
  const scene::Camera cam = sc.test.empty() ? sc.train[0].camera : sc.test[0].camera;
  int w = 0, h = 0;
  const auto centre_rays = model::block_rays(sc, cam, m.stride(), w, h);
  const int s = m.stride(), cw = w + 1;
  // The corner lattice's rays, (w + 1) x (h + 1), rendered on their own.
  std::vector<float> co, cd;
  for (int y = 0; y <= h; ++y)
    for (int x = 0; x <= w; ++x) {
      float o[3], d[3];
      scene::pixel_ray(cam, float(s * x), float(s * y), o, d);
      if (sc.effects.ndc) scene::to_ndc(cam, sc.ndc_near, o, d);
      co.insert(co.end(), o, o + 3);
      cd.insert(cd.end(), d, d + 3);
    }
  const int64_t R = int64_t(w) * h, K = int64_t(cw) * (h + 1);
  auto render = [&](const std::vector<float>& o, const std::vector<float>& d, int64_t n) {
    return m.render_content(Tensor::from_host(o, {n, 3}), Tensor::from_host(d, {n, 3}), false, 0, nullptr);
  };
  const auto centre = render(centre_rays.origins, centre_rays.directions, R);
  const auto corner = render(co, cd, K);
  const auto c0 = centre.c.to_host(), c1 = corner.c.to_host();
  const auto a0 = centre.acc.to_host(), a1 = corner.acc.to_host();
  const auto k0 = centre.kept_acc.to_host(), k1 = corner.kept_acc.to_host();
  const auto d0 = centre.depth.to_host(), d1 = corner.depth.to_host();
  const int E = int(c0.size() / size_t(R));
  std::vector<double> c(c0.size()), a(static_cast<size_t>(R)), k(static_cast<size_t>(R)), d(static_cast<size_t>(R));
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const size_t b = size_t(y) * w + x;
      const size_t q[4] = {size_t(y) * cw + x, size_t(y) * cw + x + 1, size_t(y + 1) * cw + x, size_t(y + 1) * cw + x + 1};
      for (int e = 0; e < E; ++e) {
        double v = 4.0 * c0[b * E + size_t(e)];
        for (size_t j : q) v += c1[j * E + size_t(e)];
        c[b * E + size_t(e)] = v / 8;
      }
      auto mix = [&](const std::vector<float>& v0, const std::vector<float>& v1) {
        return (4.0 * v0[b] + v1[q[0]] + v1[q[1]] + v1[q[2]] + v1[q[3]]) / 8;
      };
      a[b] = mix(a0, a1), k[b] = mix(k0, k1), d[b] = mix(d0, d1);
    }
  const model::RegionSpace space = model::RegionSpace::of(m.features.geo, sc);
  const model::RegionHead everything(model::Region::parse("sphere:0,0,0,1e6", {cam}), space);
  // Every block refined, in chunks that cut across rows; shaded per sample (this scene keeps few samples).
  const auto cc = m.render_camera_content(sc, cam, 333, &everything, model::kQuincunx, 0.0f);
  CHECK(cc.refined == R);
  CHECK(worst_rel(cc.content.c.to_host(), c) < 1e-6);
  CHECK(worst_rel(cc.content.acc.to_host(), a) < 1e-6);
  CHECK(worst_rel(cc.content.kept_acc.to_host(), k) < 1e-6);
  CHECK(worst_rel(cc.content.depth.to_host(), d) < 1e-6);
  const auto kept = cc.content.kept_acc.to_host();
  for (size_t i = 0; i < kept.size(); ++i)
    if (kept[i] > 1e-3f) CHECK(cc.region_mask[i] == doctest::Approx(1.0).epsilon(1e-4));
  // Centre and corner rays shaded per depth slab (as on fern): the same geometry, SICT close but merged.
  const auto slab = m.render_camera_content(sc, cam, 40, nullptr, model::kQuincunx, 0.0f, 0.0f);
  CHECK(slab.slab_shaded);
  CHECK(worst_rel(slab.content.acc.to_host(), a) < 1e-6);
  CHECK(worst_rel(slab.content.kept_acc.to_host(), k) < 1e-5);
  CHECK(worst_rel(slab.content.c.to_host(), c) < 0.1);
  // Refined only at edges: a block left alone is its centre ray exactly.
  const auto edges = m.render_camera_content(sc, cam, 4096, nullptr, model::kQuincunx, 0.3f);
  const auto ae = edges.content.acc.to_host();
  CHECK(edges.refined > 0);
  CHECK(edges.refined < R);
  int64_t same = 0;
  for (int64_t b = 0; b < R; ++b) same += ae[size_t(b)] == a0[size_t(b)] ? 1 : 0;
  CHECK(same >= R - edges.refined);
  // The names a user types.
  CHECK(model::parse_supersample("quincunx") == model::kQuincunx);
  CHECK(model::parse_supersample("3") == 3);
  CHECK(model::supersample_name(model::kQuincunx) == "quincunx");
  CHECK(model::supersample_name(2) == "2x2");
  for (int n : {1, 2, 3, model::kMaxSupersample, model::kQuincunx})  // every name written reads back
    CHECK(model::parse_supersample(model::supersample_name(n)) == n);
  testing::expect_error([] { model::parse_supersample("3x2"); }, "supersample '3x2'");
  testing::expect_error([] { model::parse_supersample("9"); }, "expected 1..8 (n x n rays a block) or quincunx");
  testing::expect_error([] { model::parse_supersample("grid"); }, "supersample 'grid'");
}

TEST_CASE("supersampled content shaded per depth step: the same geometry, SICT on merged samples") {
  const model::StyleModel m = small_style_model();
  const scene::Scene& sc = testing::small_scene();
  const scene::Camera cam = sc.test.empty() ? sc.train[0].camera : sc.test[0].camera;
  const model::RegionSpace space = model::RegionSpace::of(m.features.geo, sc);
  const model::RegionHead everything(model::Region::parse("sphere:0,0,0,1e6", {cam}), space);
  constexpr float kNever = 1e30f, kAlways = 0.0f;
  for (int n : {2, 3}) {
    CAPTURE(n);
    const auto exact = m.render_camera_content(sc, cam, 333, &everything, n, 0.0f, kNever);
    const auto merged = m.render_camera_content(sc, cam, 333, &everything, n, 0.0f, kAlways);
    CHECK_FALSE(exact.merged);
    CHECK(merged.merged);
    CHECK(merged.refined == exact.refined);
    // Geometry per sub-ray either way: opacity, depth, kept opacity and the region's share agree.
    auto worst = [](const std::vector<float>& a, const std::vector<float>& b) {
      double x = a.size() == b.size() ? 0 : 1e9;
      for (size_t i = 0; i < a.size() && i < b.size(); ++i) x = std::max(x, double(std::abs(a[i] - b[i])));
      return x;
    };
    CHECK(worst(merged.content.acc.to_host(), exact.content.acc.to_host()) < 1e-6);
    CHECK(worst(merged.content.depth.to_host(), exact.content.depth.to_host()) < 1e-5);
    CHECK(worst(merged.content.kept_acc.to_host(), exact.content.kept_acc.to_host()) < 1e-5);
    CHECK(worst(merged.region_mask, exact.region_mask) < 1e-4);
    CHECK(merged.pixel_acc == exact.pixel_acc);
    // SICT's output: the shade of the merged features, close to the mean of the sub-rays' shades (on
    // this scene's smooth features) but not the same numbers.
    const auto cm = merged.content.c.to_host(), ce = exact.content.c.to_host();
    double scale = 0;
    for (float v : ce) scale = std::max(scale, double(std::abs(v)));
    CHECK(worst(cm, ce) < 0.1 * scale);
    CHECK(worst(cm, ce) > 0.0);
  }
  // The default decides by the centre rays' kept samples: this small scene keeps few, so the exact average.
  const auto centres = m.render_camera_content(sc, cam, 4096, nullptr, 1);
  CHECK(centres.content.kept < int64_t(model::kMergeKeptPerRay) * centres.width * centres.height);
  CHECK_FALSE(m.render_camera_content(sc, cam, 4096, nullptr, 3, 0.0f).merged);
}

TEST_CASE("centre rays shaded per depth slab after a first call that keeps many samples a ray") {
  const model::StyleModel m = small_style_model();
  const scene::Scene& sc = testing::small_scene();
  const scene::Camera cam = sc.test.empty() ? sc.train[0].camera : sc.test[0].camera;
  constexpr float kNever = 1e30f, kAlways = 0.0f;
  constexpr int kChunk = 40;  // several renderer calls (a 12 x 12 map); the first is shaded per sample either way
  const auto exact = m.render_camera_content(sc, cam, kChunk, nullptr, 1, 0.0f, kNever);
  const auto slab = m.render_camera_content(sc, cam, kChunk, nullptr, 1, 0.0f, kAlways);
  CHECK_FALSE(exact.slab_shaded);
  CHECK(slab.slab_shaded);
  CHECK(slab.content.kept == exact.content.kept);
  const auto ae = exact.content.acc.to_host(), as = slab.content.acc.to_host();
  const auto ke = exact.content.kept_acc.to_host(), ks = slab.content.kept_acc.to_host();
  const auto de = exact.content.depth.to_host(), ds = slab.content.depth.to_host();
  const auto ce = exact.content.c.to_host(), cs = slab.content.c.to_host();
  const int E = int(ce.size() / ae.size());
  REQUIRE(ae.size() > size_t(kChunk));
  double scale = 0, first = 0, later = 0, geometry = 0;
  for (float v : ce) scale = std::max(scale, double(std::abs(v)));
  for (size_t r = 0; r < ae.size(); ++r) {
    geometry = std::max({geometry, double(std::abs(ae[r] - as[r])), double(std::abs(ke[r] - ks[r])),
                         double(std::abs(de[r] - ds[r])) * 1e-1});
    for (int e = 0; e < E; ++e) {
      const double d = std::abs(ce[r * E + size_t(e)] - cs[r * E + size_t(e)]);
      double& worst = r < size_t(kChunk) ? first : later;
      worst = testing::max_or_nan(worst, d);
    }
  }
  CHECK(geometry < 1e-5);     // the same samples and weights
  CHECK(first == 0.0);        // the deciding call: every sample shaded, as without merging
  CHECK(later > 0.0);         // then one shade per slab: not the same numbers...
  CHECK(later < 0.1 * scale);  // ...but close on this scene's smooth features
  // The default decides by the first call's kept samples: this small scene keeps few, so every sample.
  CHECK_FALSE(m.render_camera_content(sc, cam, kChunk, nullptr, 1).slab_shaded);
}

TEST_CASE("inference's march step: NDC scenes a sample a voxel, others as trained; training's step untouched") {
  model::Geometry g = testing::small_geometry();
  REQUIRE_FALSE(g.ndc);
  CHECK(model::StyleModel::default_inference_step_ratio(g) == g.step_ratio);
  g.ndc = true;
  CHECK(model::StyleModel::default_inference_step_ratio(g) == 1.0f);
  g.step_ratio = 2.0f;  // never finer than the trained step
  CHECK(model::StyleModel::default_inference_step_ratio(g) == 2.0f);
  const model::Geometry& trained = testing::small_geometry();
  const model::Geometry coarse = trained.with_step_ratio(2.0f * trained.step_ratio);
  CHECK(coarse.step == doctest::Approx(2.0 * trained.step).epsilon(1e-5));
  CHECK(coarse.mask_step == trained.mask_step);  // the mask keeps the step it was built with
  CHECK(coarse.density.params.same_buffer(trained.density.params));  // shared, not copied
  testing::expect_error([&] { trained.with_step_ratio(0.0f); }, "step ratio must be positive");

  // On the small scene (not NDC) the default is the trained step; twice as coarse halves the samples and
  // keeps the opacity and content close, and the model's own (training) geometry is unchanged.
  model::StyleModel m = small_style_model();
  CHECK(m.inference_step_ratio == trained.step_ratio);
  const scene::Scene& sc = testing::small_scene();
  const scene::Camera cam = sc.test.empty() ? sc.train[0].camera : sc.test[0].camera;
  const auto fine = m.render_camera_content(sc, cam);
  m.inference_step_ratio = 2.0f * trained.step_ratio;
  const auto half = m.render_camera_content(sc, cam);
  CHECK(m.features.geo.step == trained.step);
  CHECK(m.inference_geometry().step == doctest::Approx(2.0 * trained.step).epsilon(1e-5));
  CHECK(double(half.content.samples) < 0.6 * double(fine.content.samples));
  CHECK(double(half.content.samples) > 0.4 * double(fine.content.samples));
  const auto af = fine.content.acc.to_host(), ah = half.content.acc.to_host();
  double worst = 0, mean = 0;
  for (size_t r = 0; r < af.size(); ++r) {
    worst = testing::max_or_nan(worst, double(std::abs(af[r] - ah[r])));
    mean += std::abs(af[r] - ah[r]) / double(af.size());
  }
  CHECK(worst > 0.0);  // a coarser quadrature: not the same numbers...
  CHECK(mean < 0.02);  // ...but the same geometry
}

TEST_CASE("blocks to refine: the blocks on either side of an edge, nothing on flat or gently sloping maps") {
  // A map of w x h blocks, 3 channels; channel 2 is constant (never triggers, no division by a zero spread).
  auto map = [](int w, int h, auto value) {
    std::vector<float> c(size_t(w) * h * 3), a(size_t(w) * h, 0.5f);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x)
        for (int k = 0; k < 3; ++k) c[(size_t(y) * w + x) * 3 + k] = k == 2 ? 7.0f : value(x, y, k);
    return std::make_pair(c, a);
  };
  const int w = 64, h = 9;
  auto count = [](const std::vector<uint8_t>& r) { return std::count(r.begin(), r.end(), uint8_t(1)); };
  {  // flat: nothing; contrast 0: everything (the exact average)
    const auto [c, a] = map(w, h, [](int, int, int) { return 1.0f; });
    CHECK(count(model::blocks_to_refine(c, 3, a, w, h, model::kRefineContrast)) == 0);
    CHECK(count(model::blocks_to_refine(c, 3, a, w, h, 0.0f)) == w * h);
  }
  {  // a gentle ramp (neighbours 1 apart, spread ~18.5): a linear map's centre is its block mean
    const auto [c, a] = map(w, h, [](int x, int, int k) { return float(x) * (k + 1); });
    CHECK(count(model::blocks_to_refine(c, 3, a, w, h, model::kRefineContrast)) == 0);
  }
  {  // a step in channel 0 between columns 40 and 41: exactly those two columns, every row
    const auto [c, a] = map(w, h, [](int x, int, int k) { return k == 0 ? (x > 40 ? 3.0f : 0.0f) : 0.01f * x; });
    const auto r = model::blocks_to_refine(c, 3, a, w, h, model::kRefineContrast);
    CHECK(count(r) == 2 * h);
    for (int y = 0; y < h; ++y) CHECK((r[size_t(y) * w + 40] && r[size_t(y) * w + 41]));
  }
  {  // an opacity step alone (a silhouette over a flat colour): refined by the opacity, one block each side
    auto [c, a] = map(w, h, [](int, int, int) { return 1.0f; });
    a[size_t(4) * w + 10] = 1.0f;  // one block: itself and its 8 neighbours
    const auto r = model::blocks_to_refine(c, 3, a, w, h, 0.3f);
    CHECK(count(r) == 9);
    CHECK(r[size_t(3) * w + 9] == 1);
    CHECK(r[size_t(5) * w + 11] == 1);
    CHECK(r[size_t(4) * w + 12] == 0);
  }
  testing::expect_error([] { model::blocks_to_refine(std::vector<float>(10), 3, std::vector<float>(4), 2, 2, 0.1f); },
                        "does not match");
}

TEST_CASE("refined supersampling: the n x n mean where blocks_to_refine says, the centre ray elsewhere") {
  const model::StyleModel m = small_style_model();
  const scene::Scene& sc = testing::small_scene();
  const scene::Camera cam = sc.test.empty() ? sc.train[0].camera : sc.test[0].camera;
  const auto centre = m.render_camera_content(sc, cam, 4096, nullptr, 1);
  const auto c1 = centre.content.c.to_host(), a1 = centre.content.acc.to_host(), k1 = centre.content.kept_acc.to_host();
  const size_t blocks = size_t(centre.width) * centre.height;
  for (int n : {2, 3}) {
    CAPTURE(n);
    const auto all = m.render_camera_content(sc, cam, 4096, nullptr, n, 0.0f);
    CHECK(all.refined == int64_t(blocks));
    // A contrast nothing reaches: the centre rays' map exactly, whatever n.
    const auto none = m.render_camera_content(sc, cam, 4096, nullptr, n, 1e30f);
    CHECK(none.refined == 0);
    CHECK(none.content.c.to_host() == c1);
    CHECK(none.content.acc.to_host() == a1);
    // In between: each block is one or the other, as the test on the centre map decides.
    const float contrast = 0.3f;
    const auto want = model::blocks_to_refine(c1, 32, a1, centre.width, centre.height, contrast);
    const auto some = m.render_camera_content(sc, cam, 333, nullptr, n, contrast);  // chunks cut across rows
    const int64_t refined = std::count(want.begin(), want.end(), uint8_t(1));
    CHECK(some.refined == refined);
    CHECK(refined > 0);
    CHECK(refined < int64_t(blocks));
    const auto cs = some.content.c.to_host(), ca = all.content.c.to_host(), ks = some.content.kept_acc.to_host(),
               ka = all.content.kept_acc.to_host();
    int bad = 0;
    for (size_t b = 0; b < blocks; ++b) {
      const auto& c_ref = want[b] ? ca : c1;
      const float k_ref = want[b] ? ka[b] : k1[b];
      if (std::abs(ks[b] - k_ref) > 1e-5f * (1 + std::abs(k_ref))) ++bad;
      for (size_t e = 0; e < 32; ++e)
        if (std::abs(cs[b * 32 + e] - c_ref[b * 32 + e]) > 1e-5f * (1 + std::abs(c_ref[b * 32 + e]))) ++bad;
    }
    CHECK(bad == 0);
  }
}

TEST_CASE("pixel opacity rendered near silhouettes only equals one ray a pixel everywhere") {
  model::StyleModel m = small_style_model();
  m.features.geo.has_background = true;  // pixel_acc is rendered for scenes with a background
  const scene::Scene& sc = testing::small_scene();
  const scene::Camera cam = sc.test.empty() ? sc.train[0].camera : sc.test[0].camera;
  const auto full = model::render_geometry(m.features.geo, sc, cam, 4096).acc;
  for (int n : {1, 2, 3}) {
    CAPTURE(n);
    const auto cc = m.render_camera_content(sc, cam, 4096, nullptr, n);
    REQUIRE(cc.pixel_acc.size() == full.size());
    double worst = 0;
    int settled = 0, rendered = 0;
    for (size_t i = 0; i < full.size(); ++i) {
      worst = testing::max_or_nan(worst, double(std::abs(cc.pixel_acc[i] - full[i])));
      (cc.pixel_acc[i] == 0.0f || cc.pixel_acc[i] == 1.0f ? settled : rendered) += 1;
    }
    CHECK(worst < 2e-3);  // settled blocks take 0 or 1 where the truth is within 1e-3 of it
    CHECK(rendered > 0);  // the generated scene has silhouettes in view
    CHECK(settled > 0);   // and empty space around them
  }
}

TEST_CASE("content rendered once for several styles gives each the frames it gets alone") {
  model::StyleModel m = small_style_model();
  m.features.geo.has_background = true;
  m.features.geo.background = {1.0f, 1.0f, 1.0f};
  const scene::Scene& sc = testing::small_scene();
  std::vector<scene::Camera> cams{sc.train[0].camera, sc.train[1].camera};
  const auto contents = eval::content_frames(m, sc, cams, 4096, 2);
  REQUIRE(contents.size() == cams.size());
  for (uint64_t seed : {11u, 23u}) {
    CAPTURE(seed);
    const style::StyleCode code = random_code(seed);
    const auto shared = eval::stylerf_frames(m, contents, cams, code, true);
    const auto alone = eval::stylerf_frames(m, sc, cams, code, true, 4096, 2);
    REQUIRE(shared.size() == alone.size());
    for (size_t i = 0; i < shared.size(); ++i) CHECK(shared[i].data == alone[i].data);
  }
  testing::expect_error([&] { eval::stylerf_frames(m, contents, {cams[0]}, random_code(5), true); },
                        "2 contents for 1 cameras");
}

TEST_CASE("background compositing uses the rendered opacity") {
  model::StyleModel m = small_style_model();
  m.features.geo.has_background = true;
  m.features.geo.background = {0.2f, 0.4f, 0.6f};
  model::StyleModel::CameraContent cc;
  cc.width = 2;
  cc.height = 1;
  cc.content.acc = Tensor::from_host({0.0f, 1.0f}, {2});
  const int s = m.stride(), W = 2 * s, H = s;
  std::vector<float> rgb(size_t(3) * W * H, 0.9f);
  m.over_background(rgb, cc, W, H);
  // Pixel 0 of row 0 lies left of block 0's centre: opacity clamps to block 0 (0) -> the background.
  CHECK(rgb[0] == doctest::Approx(0.2f));
  CHECK(rgb[2] == doctest::Approx(0.6f));
  // The last pixel lies right of block 1's centre: opacity 1 -> unchanged.
  CHECK(rgb[rgb.size() - 1] == doctest::Approx(0.9f));
  m.features.geo.has_background = false;
  std::vector<float> same(size_t(3) * W * H, 0.9f);
  m.over_background(same, cc, W, H);
  CHECK(same == std::vector<float>(size_t(3) * W * H, 0.9f));
}

TEST_CASE("background compositing at the image's resolution: a per-pixel opacity, rendered by the geometry") {
  // A map coarser than the image (stride s) used to composite with its opacity upsampled from the block
  // centres, so silhouettes came out as s x s blocks. The content now carries one opacity per pixel.
  const auto& sc = testing::small_scene();
  model::StyleModel m = small_style_model();
  const auto& cam = sc.test[0].camera;
  REQUIRE(m.stride() > 1);
  m.features.geo.has_background = false;  // no background to composite over: nothing extra is rendered
  CHECK(m.render_camera_content(sc, cam).pixel_acc.empty());
  m.features.geo.has_background = true;
  m.features.geo.background = {0.2f, 0.4f, 0.6f};
  const auto rendered = m.render_camera_content(sc, cam);
  REQUIRE(rendered.pixel_acc.size() == size_t(cam.width) * cam.height);
  const auto full = model::render_geometry(m.features.geo, sc, cam, 8192).acc;
  for (size_t i = 0; i < full.size(); ++i)  // away from silhouettes 0 or 1 (the next test), else the same ray's
    CHECK(std::abs(rendered.pixel_acc[i] - full[i]) < 2e-3f);
  // over_background uses each pixel's own opacity: a checkerboard of 0 and 1 at pixel scale, which no
  // upsampling of block opacities can make.
  model::StyleModel::CameraContent cc;
  const int s = m.stride(), W = 2 * s, H = 2 * s;
  cc.width = 2;
  cc.height = 2;
  cc.content.acc = Tensor::from_host({0.5f, 0.5f, 0.5f, 0.5f}, {4});
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) cc.pixel_acc.push_back(float((x + y) % 2));
  std::vector<float> rgb(size_t(3) * W * H, 0.9f);
  m.over_background(rgb, cc, W, H);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x)
      CHECK(rgb[(size_t(y) * W + x) * 3] == doctest::Approx((x + y) % 2 ? 0.9f : 0.2f));
}

TEST_CASE("style codes: interpolation weights") {
  const style::StyleCode a = random_code(1), b = random_code(2);
  const style::StyleCode only_a = style::mix_codes({a, b}, {1.0f, 0.0f});
  CHECK(only_a.T.to_host() == a.T.to_host());
  CHECK(only_a.std.to_host() == a.std.to_host());
  const style::StyleCode half = style::mix_codes({a, b}, {0.5f, 0.5f});
  const auto ha = a.mean.to_host(), hb = b.mean.to_host(), hh = half.mean.to_host();
  for (size_t i = 0; i < hh.size(); ++i) CHECK(hh[i] == doctest::Approx(0.5 * ha[i] + 0.5 * hb[i]).epsilon(1e-6));
  testing::expect_error([&] { style::mix_codes({a, b}, {0.5f}); }, "1 weights for 2 styles");
  testing::expect_error([&] { style::mix_codes({a, b}, {0.7f, 0.7f}); }, "sum to 1");
  testing::expect_error([&] { style::mix_codes({a, b}, {1.5f, -0.5f}); }, ">= 0");
  testing::expect_error([&] { style::mix_codes({a, b}, {NAN, 1.0f}); }, "finite");
  testing::expect_error([&] { style::mix_codes({}, {}); }, "no styles");
}

TEST_CASE("style encoder: hard images, memory and disk caches") {
  const model::StyleModel m = small_style_model();
  nn::VggEncoder vgg = nn::VggEncoder::load_default();
  const fs::path dir = testing::small_work_dir() / "style_codes";
  fs::remove_all(dir);
  style::StyleEncoder enc(m.dst, vgg, dir.string());
  std::vector<std::string> keys;
  for (const auto& name : {"grey1x1.png", "rgb16.png", "cmyk.jpg"}) {
    CAPTURE(name);
    const auto e = enc.encode(fixture(name));
    CHECK_FALSE(e.from_cache);
    CHECK(testing::all_finite(e.code.T.to_host()));
    CHECK(testing::all_finite(e.code.mean.to_host()));
    CHECK(testing::all_finite(e.code.std.to_host()));
    keys.push_back(e.key);
    const auto again = enc.encode(fixture(name));
    CHECK(again.from_cache);
    CHECK(again.code.T.to_host() == e.code.T.to_host());
    CHECK(fs::exists(dir / (e.key + ".safetensors")));
  }
  CHECK(keys[0] != keys[1]);
  CHECK(keys[1] != keys[2]);
  // A grey image has (almost) no spread: its std is tiny and the stylised image still finite.
  {
    const auto grey = enc.encode(fixture("grey1x1.png")).code;
    double smax = 0;
    for (float v : grey.std.to_host()) smax = std::max(smax, double(v));
    CHECK(smax < 0.05);
    const scene::Scene& sc = testing::small_scene();
    const auto cc = m.render_camera_content(sc, sc.train[0].camera);
    CHECK(testing::all_finite(m.stylize_camera(cc, grey, sc.train[0].camera.width, sc.train[0].camera.height)));
  }
  // The trainer's cached halves draw the same crops as the one-call loader, and refuse what it refuses.
  {
    const io::Image source = style::load_style_source(fixture("rgb16.png"), 24);
    for (uint64_t seed : {1u, 2u, 3u}) {
      std::mt19937_64 a(seed), b(seed);
      CHECK(style::crop_style_image(source, 16, &a, "rgb16.png").to_host() ==
            style::load_style_image(fixture("rgb16.png"), 24, 16, &b).to_host());
      CHECK(a() == b());  // the same random draws were taken
    }
    CHECK(style::crop_style_image(source, 24, nullptr, "x").to_host() ==
          style::load_style_image(fixture("rgb16.png"), 24, 24, nullptr).to_host());
    CHECK_THROWS_WITH_AS(style::crop_style_image(source, 32, nullptr, "named.png"),
                         doctest::Contains("style image named.png: crop 32 must be a multiple of 8 in [8, 24]"), host::Error);
    CHECK_THROWS_WITH_AS(style::crop_style_image(source, 12, nullptr, "named.png"), doctest::Contains("crop 12"),
                         host::Error);
  }
  // 16-bit PNG: decoded at full precision (the fixture is ffmpeg's testsrc: saturated colours).
  const Tensor img16 = style::load_style_image(fixture("rgb16.png"), 16, 16, nullptr);
  CHECK(testing::all_finite(img16.to_host()));
  // CMYK JPEG: converted to RGB (the fixture was RGB (16x, 16y, 128) before its CMYK conversion).
  {
    const io::Image cmyk = io::load_image(fixture("cmyk.jpg"));
    REQUIRE(cmyk.width == 16);
    CHECK(cmyk.at(0, 8, 12) == doctest::Approx(12 * 16 / 255.0).epsilon(0.15));
    CHECK(cmyk.at(1, 8, 12) == doctest::Approx(8 * 16 / 255.0).epsilon(0.15));
    CHECK(cmyk.at(2, 8, 12) == doctest::Approx(128 / 255.0).epsilon(0.15));
  }
  // A fresh encoder over the same folder reads the disk cache: identical codes.
  {
    style::StyleEncoder fresh(m.dst, vgg, dir.string());
    const auto e = fresh.encode(fixture("rgb16.png"));
    CHECK(e.from_cache);
    CHECK(e.code.T.to_host() == enc.encode(fixture("rgb16.png")).code.T.to_host());
    // A damaged entry is recomputed, not trusted.
    std::ofstream((dir / (e.key + ".safetensors")).string(), std::ios::binary | std::ios::trunc) << "garbage";
    style::StyleEncoder third(m.dst, vgg, dir.string());
    const auto r = third.encode(fixture("rgb16.png"));
    CHECK_FALSE(r.from_cache);
    CHECK(r.code.T.to_host() == e.code.T.to_host());
  }
  // Another model's weights: another key.
  {
    model::StyleModel other = small_style_model();
    other.dst = style::Dst::create(true, 0, 99, "style.dst.");
    style::StyleEncoder enc2(other.dst, vgg, dir.string());
    CHECK(enc2.encode(fixture("rgb16.png")).key != keys[1]);
  }
  // Not an image: the error names the file; a folder skips it.
  const fs::path bad_dir = testing::small_work_dir() / "mixed_styles";
  fs::create_directories(bad_dir);
  std::ofstream((bad_dir / "notes.png").string()) << "this is text";
  fs::copy_file(fixture("rgb16.png"), bad_dir / "good.png", fs::copy_options::overwrite_existing);
  testing::expect_error([&] { enc.encode((bad_dir / "notes.png").string()); }, "notes.png");
  std::ostringstream log;
  const auto found = style::style_images_in(bad_dir.string(), &log);
  REQUIRE(found.size() == 1);
  CHECK(found[0].find("good.png") != std::string::npos);
  CHECK(log.str().find("notes.png") != std::string::npos);
  testing::expect_error([&] { style::style_images_in((bad_dir / "missing").string(), nullptr); }, "not a folder");
}
