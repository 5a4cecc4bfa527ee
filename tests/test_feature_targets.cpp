// Stage-2 feature targets (lib/features): the padding and map geometry with the real VGG-19, the disk cache
// (reuse, truncated file, wrong key, wrong shape, no stray files), the device gather against a double CPU
// reference written in F.interpolate(align_corners=False)'s own terms, its backward against central finite
// differences, the patch read, and the ray and patch samplers on a generated scene.
//
// Needs the VGG weights (`bash scripts/fetch_weights.sh`); the scene is generated, so ../shared is not used.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <unistd.h>

#include "host/error.hpp"
#include "host/files.hpp"
#include "host/runtime.hpp"
#include "lib/features/content_hash.hpp"
#include "lib/features/feature_sampler.hpp"
#include "lib/features/feature_targets.hpp"
#include "lib/features/target_cache.hpp"
#include "lib/features/target_gather.hpp"
#include "host/half.hpp"
#include "lib/features/target_file.hpp"
#include "lib/scene/make_scene.hpp"
#include "tests/testing.hpp"

using namespace stylerf;
using features::FeatureTargets;
using host::Tensor;
namespace fs = std::filesystem;

namespace {

// A scratch folder for this process (scene, caches), removed when the suite exits.
struct ScratchDir {
  fs::path path = fs::temp_directory_path() / ("stylerf_test_targets_" + std::to_string(::getpid()));
  ScratchDir() {
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~ScratchDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

fs::path work_dir() {
  static ScratchDir dir;
  return dir.path;
}

nn::VggEncoder& vgg() {
  static nn::VggEncoder e = nn::VggEncoder::load_default();
  return e;
}

// A textured image in [0,1]: stripes and blobs at several scales, so relu3_1 varies from pixel to pixel.
std::vector<float> texture(int w, int h, uint64_t seed, int x_offset = 0) {
  const std::vector<float> f = testing::random_uniform(12, seed, 0.05f, 0.6f);
  std::vector<float> rgb(size_t(w) * h * 3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) {
        const double X = x + x_offset, v = 0.5 + 0.25 * std::sin(f[size_t(c)] * X + f[size_t(c) + 3] * y) +
                                           0.2 * std::cos(f[size_t(c) + 6] * X * 0.7 - f[size_t(c) + 9] * y * 1.3) +
                                           0.05 * (((x + x_offset) / 3 + y / 5) % 2);
        rgb[(size_t(y) * w + x) * 3 + c] = float(std::clamp(v, 0.0, 1.0));
      }
  return rgb;
}

// An in-memory scene of `views` w x h textured images (cameras looking down -z); enough for targets and
// patches, no files.
scene::Scene memory_scene(int w, int h, int views, uint64_t seed) {
  scene::Scene s;
  s.name = "memory";
  s.format = "blender";
  for (int i = 0; i < views; ++i) {
    scene::View v;
    v.camera.width = w;
    v.camera.height = h;
    v.camera.fx = v.camera.fy = float(w);
    v.camera.cx = w * 0.5f;
    v.camera.cy = h * 0.5f;
    v.camera.c2w[0][3] = 0.1f * i;
    v.image_path = "memory/r_" + std::to_string(i) + ".png";
    v.rgb = texture(w, h, seed + uint64_t(i));
    s.train.push_back(v);
  }
  return s;
}

// 40 px, 8 training views; 24 px and 4 training views under STYLERF_TEST_SMALL (the simulator): the cache
// case runs the encoder over every view once per subcase and again in most of them.
const int kSceneSize = testing::small_run() ? 24 : 40;
const int kSceneTrainViews = testing::small_run() ? 4 : 8;

const scene::Scene& generated_scene() {
  static scene::Scene s = [] {
    scene::MakeSceneOptions mo;
    mo.size = kSceneSize;
    mo.views = kSceneTrainViews == 8 ? 10 : 6;  // views 0 and 5 go to val and test, the rest to train
    const std::string dir = (work_dir() / "scene").string();
    scene::make_scene(dir, mo);
    return scene::load_scene(dir);
  }();
  return s;
}

// ---- double reference of the gather, in F.interpolate(align_corners=False)'s terms ------------------------
// Source index of an output position: max(p * in/out - 0.5, 0) with in/out = 1/4 and p = dst + 0.5; taps
// h1 = floor, h1p = (h1 < in - 1), weights (1 - lambda, lambda). Positions past the last map pixel keep
// reading it (i0 capped at n - 1, lambda then irrelevant).
struct RefAxis {
  int i0, i1;
  double l;
};
RefAxis ref_axis(double p, int n) {
  const double src = std::max(p / 4.0 - 0.5, 0.0);
  const int i0 = std::min(int(std::floor(src)), n - 1);
  return {i0, i0 + (i0 < n - 1 ? 1 : 0), src - i0};
}

// maps [V][hf][wf][C] -> [R][C] at (view, pixel_xy).
std::vector<double> ref_gather(const std::vector<double>& maps, int hf, int wf, int C, const std::vector<int32_t>& view,
                               const std::vector<float>& xy) {
  const size_t R = view.size();
  std::vector<double> out(R * size_t(C));
  for (size_t r = 0; r < R; ++r) {
    const RefAxis ax = ref_axis(xy[2 * r], wf), ay = ref_axis(xy[2 * r + 1], hf);
    auto at = [&](int i, int j, int c) { return maps[((size_t(view[r]) * hf + i) * wf + j) * C + c]; };
    for (int c = 0; c < C; ++c)
      out[r * C + c] = (1 - ay.l) * ((1 - ax.l) * at(ay.i0, ax.i0, c) + ax.l * at(ay.i0, ax.i1, c)) +
                       ay.l * ((1 - ax.l) * at(ay.i1, ax.i0, c) + ax.l * at(ay.i1, ax.i1, c));
  }
  return out;
}

struct GatherCase {
  int V, hf, wf, C, R;
  std::vector<float> maps, xy;
  std::vector<int32_t> view;
};

// Random maps and positions that cover the borders: pixel centres, the first/last half pixel, positions
// a little outside the image, exact map-pixel centres (weights 0/1) and map-pixel edges (weights 1/2).
GatherCase make_case(int V, int hf, int wf, int C, int R, uint64_t seed) {
  GatherCase g{V, hf, wf, C, R, testing::random_normal(size_t(V) * hf * wf * C, seed), {}, {}};
  const std::vector<float> u = testing::random_uniform(2 * size_t(R), seed + 1, -3.0f, 4.0f * std::max(hf, wf) + 3.0f);
  const std::vector<float> pick = testing::random_uniform(size_t(R), seed + 2, 0.0f, float(V) - 1e-3f);
  for (int r = 0; r < R; ++r) {
    g.view.push_back(int32_t(pick[size_t(r)]));
    float x = std::min(u[2 * size_t(r)], 4.0f * wf + 3.0f), y = std::min(u[2 * size_t(r) + 1], 4.0f * hf + 3.0f);
    switch (r % 6) {
      case 1: x = std::floor(x) + 0.5f, y = std::floor(y) + 0.5f; break;    // pixel centres
      case 2: x = 4.0f * (r % wf) + 2.0f, y = 4.0f * (r % hf) + 2.0f; break;  // map-pixel centres
      case 3: x = 4.0f * (r % wf), y = 4.0f * (r % hf); break;                // map-pixel edges
      case 4: x = 0.5f, y = 4.0f * hf - 0.5f; break;                          // first / last pixel
      default: break;
    }
    g.xy.push_back(x);
    g.xy.push_back(y);
  }
  return g;
}

// The maps on the device as `dtype`. F16 needs g's values rounded to half first (half_rounded), so the
// reference reads exactly what the kernel does.
Tensor device_maps(const GatherCase& g, host::DType dtype = host::DType::F32) {
  if (dtype == host::DType::F32) return Tensor::from_host(g.maps, {g.V, g.hf, g.wf, g.C});
  Tensor t({g.V, g.hf, g.wf, g.C}, dtype, "f16 maps");
  std::vector<uint16_t> bits(g.maps.size());
  host::floats_to_halves(g.maps.data(), g.maps.size(), bits.data());
  t.write_bytes(0, bits.data(), t.bytes());
  return t;
}

GatherCase half_rounded(GatherCase g) {
  for (float& x : g.maps) x = host::half_to_float(host::float_to_half(x));
  return g;
}
Tensor view_tensor(const std::vector<int32_t>& v) { return Tensor::from_host(v, {int64_t(v.size())}, "view index"); }

}  // namespace

TEST_CASE("reflect padding folds as often as needed and keeps the image at the top left") {
  // Reflection stated another way: mirror about 0 and about n - 1 until the index is inside.
  auto mirrored = [](int i, int n) {
    if (n == 1) return 0;
    while (i < 0 || i >= n) i = i < 0 ? -i : 2 * (n - 1) - i;
    return i;
  };
  for (int n = 1; n <= 6; ++n)
    for (int i = -20; i <= 20; ++i) CHECK_MESSAGE(features::reflect_index(i, n) == mirrored(i, n), "i=" << i << " n=" << n);
  CHECK(features::target_map_size(200) == 50);
  CHECK(features::target_map_size(378) == 95);
  CHECK(features::target_map_size(1) == 1);

  // 3 x 2 image with value 10 * y + x in channel 0: padded to 8 x 8, row 2 mirrors row 0 (height 2).
  std::vector<float> rgb(2 * 3 * 3, 0.0f);
  for (int y = 0; y < 2; ++y)
    for (int x = 0; x < 3; ++x) rgb[(size_t(y) * 3 + x) * 3] = float(10 * y + x);
  int ph = 0, pw = 0;
  const std::vector<float> p = features::pad_to_multiple_chw(rgb, 2, 3, 8, ph, pw);
  REQUIRE(ph == 8);
  REQUIRE(pw == 8);
  CHECK(p[0 * 8 + 0] == 0.0f);
  CHECK(p[1 * 8 + 2] == 12.0f);
  CHECK(p[0 * 8 + 3] == 1.0f);   // x = 3 mirrors x = 1
  CHECK(p[0 * 8 + 4] == 0.0f);   // x = 4 mirrors x = 0
  CHECK(p[0 * 8 + 5] == 1.0f);   // and folds back
  CHECK(p[2 * 8 + 0] == 0.0f);   // y = 2 mirrors y = 0
  CHECK(p[3 * 8 + 1] == 11.0f);  // y = 3 is row 1 again
  testing::expect_error([&] { features::pad_to_multiple_chw(rgb, 2, 4, 8, ph, pw); }, "values for a 4x2 RGB image");
}

TEST_CASE("relu3_1 targets: layout, crop, and map pixel j covering image pixels 4j..4j+3") {
  // Against the encoder run directly on the padded image: channels innermost, cropped to ceil(n/4).
  for (auto [w, h] : {std::pair{48, 40}, std::pair{45, 37}, std::pair{5, 3}}) {
    CAPTURE(w);
    CAPTURE(h);
    const std::vector<float> rgb = texture(w, h, 5);
    const std::vector<float> t = features::compute_view_targets(vgg(), rgb, h, w);
    const int hf = (h + 3) / 4, wf = (w + 3) / 4;
    REQUIRE(t.size() == size_t(hf) * wf * 256);
    int ph = 0, pw = 0;
    const std::vector<float> padded = features::pad_to_multiple_chw(rgb, h, w, 8, ph, pw);
    const nn::VggFeatures f = vgg().forward(Tensor::from_host(padded, {1, 3, ph, pw}), 3, false);
    const std::vector<float> ref = f[2].to_host();
    const int mh = ph / 4, mw = pw / 4;
    double worst = 0;
    for (int i = 0; i < hf; ++i)
      for (int j = 0; j < wf; ++j)
        for (int c = 0; c < 256; ++c)
          worst = testing::max_or_nan(worst, double(std::fabs(t[(size_t(i) * wf + j) * 256 + c] - ref[(size_t(c) * mh + i) * mw + j])));
    CHECK(worst == 0.0);
    CHECK(testing::all_finite(t));
  }

  // Shift the content 4 pixels left: away from the borders (relu3_1 sees 24 pixels), the map shifts by
  // exactly one column. A map whose pixels were not aligned to 4-pixel blocks could not do this.
  const int w = 64, h = 48, wf = 16;
  const std::vector<float> a = features::compute_view_targets(vgg(), texture(w, h, 9, 0), h, w);
  const std::vector<float> b = features::compute_view_targets(vgg(), texture(w, h, 9, 4), h, w);
  double scale = 0, diff_shifted = 0, diff_unshifted = 0;
  for (int i = 3; i <= 8; ++i)
    for (int j = 3; j <= 10; ++j)
      for (int c = 0; c < 256; ++c) {
        const float va = a[(size_t(i) * wf + j + 1) * 256 + c], vb = b[(size_t(i) * wf + j) * 256 + c];
        scale = std::max(scale, double(std::fabs(va)));
        diff_shifted = std::max(diff_shifted, double(std::fabs(va - vb)));
        diff_unshifted = std::max(diff_unshifted, double(std::fabs(a[(size_t(i) * wf + j) * 256 + c] - vb)));
      }
  INFO("max |relu3_1| " << scale << ", shifted diff " << diff_shifted << ", unshifted diff " << diff_unshifted);
  CHECK(scale > 1.0);
  CHECK(diff_shifted <= 1e-4 * scale);
  CHECK(diff_unshifted > 0.05 * scale);  // the content does move: the shifted match is not trivial
}

TEST_CASE("content hash: stable, order- and boundary-sensitive") {
  auto h = [](const std::vector<std::string>& parts) {
    features::ContentHash c;
    for (const auto& p : parts) c.text(p);
    return c.hex();
  };
  CHECK(h({"ab", "c"}) == h({"ab", "c"}));
  CHECK(h({"ab", "c"}) != h({"a", "bc"}));
  CHECK(h({"ab", "c"}) != h({"c", "ab"}));
  CHECK(h({"abcdefgh12"}) != h({"abcdefgh13"}));
  CHECK(h({}).size() == 16);
  const fs::path f = work_dir() / "hashme.bin";
  std::ofstream(f, std::ios::binary) << std::string(3000000, 'x');
  const std::string a = features::ContentHash().file(f.string()).hex();
  std::ofstream(f, std::ios::binary | std::ios::app) << 'y';
  CHECK(features::ContentHash().file(f.string()).hex() != a);
  testing::expect_error([&] { features::ContentHash().file((work_dir() / "nope").string()); }, "cannot be opened");
}

TEST_CASE("targets cache: computed once, reused, and recomputed when truncated, mismatched or of another shape") {
  const scene::Scene& sc = generated_scene();
  const int S = kSceneSize, V = kSceneTrainViews, last = V - 1;
  REQUIRE(sc.train.size() == size_t(V));
  features::TargetCacheOptions opts;
  opts.dir = (work_dir() / "cache").string();
  fs::remove_all(opts.dir);  // doctest reruns the case once per subcase: start each run with no cache
  std::ostringstream log;
  opts.log = &log;

  const FeatureTargets first = features::load_or_compute_targets(sc, vgg(), opts);
  CHECK_FALSE(first.from_cache);
  CHECK(first.maps.shape() == host::Shape{V, S / 4, S / 4, 256});
  CHECK(first.image_width == S);
  CHECK(log.str().find("views/s") != std::string::npos);
  const std::string path = features::target_cache_path(opts.dir, first.key);
  REQUIRE(fs::exists(path));
  // Nothing else in the folder: the write went through a temporary file that was renamed.
  CHECK(std::distance(fs::directory_iterator(opts.dir), fs::directory_iterator()) == 1);
  CHECK(first.maps.dtype() == host::DType::F16);  // training's storage
  const std::vector<float> want = features::maps_to_host(first);
  // Spot-check that the stored maps are the targets of the views, in order, rounded to half.
  std::vector<float> vl = features::compute_view_targets(vgg(), sc.train[size_t(last)].rgb, S, S);
  for (float& x : vl) x = host::half_to_float(host::float_to_half(x));
  CHECK(std::equal(vl.begin(), vl.end(), want.begin() + std::ptrdiff_t(last * vl.size())));

  log.str("");
  const FeatureTargets again = features::load_or_compute_targets(sc, vgg(), opts);
  CHECK(again.from_cache);
  CHECK(again.key == first.key);
  CHECK(features::maps_to_host(again) == want);
  CHECK(log.str().find("read from") != std::string::npos);

  SUBCASE("a truncated file is recomputed and replaced") {
    fs::resize_file(path, fs::file_size(path) / 2);
    log.str("");
    const FeatureTargets t = features::load_or_compute_targets(sc, vgg(), opts);
    CHECK_FALSE(t.from_cache);
    CHECK(log.str().find("recomputing") != std::string::npos);
    CHECK(features::maps_to_host(t) == want);
    CHECK(features::load_or_compute_targets(sc, vgg(), opts).from_cache);
  }
  SUBCASE("a file holding another key, another shape, or malformed metadata is recomputed") {
    const std::vector<int64_t> other_shape{V / 2, 2 * (S / 4), S / 4, 256};  // [4, 20, 10, 256] at 40 px
    const std::string other_text = "have shape [" + std::to_string(V / 2) + ", " + std::to_string(2 * (S / 4)) + ", " +
                                   std::to_string(S / 4) + ", 256]";
    for (int variant = 0; variant < 4; ++variant) {
      CAPTURE(variant);
      // Rewrite the file with the same data bytes under another key, shape, dtype or a malformed key.
      std::vector<uint8_t> data;
      {
        std::ifstream in(path, std::ios::binary);
        uint64_t hlen = 0;
        in.read(reinterpret_cast<char*>(&hlen), 8);
        in.seekg(std::streamoff(8 + hlen));
        data.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
      }
      nlohmann::json meta = {{"key", first.key}};
      host::Shape shape = first.maps.shape();
      host::DType dtype = host::DType::F16;
      if (variant == 0) meta["key"] = "0123456789abcdef";
      if (variant == 1) shape = other_shape;  // as many values, another shape
      if (variant == 2) meta["key"] = 42;     // not a string: a json type error, still just "recompute"
      if (variant == 3) dtype = host::DType::F32, shape[0] /= 2;  // as many bytes, stored as f32
      host::write_atomic_with(path, [&](const std::string& tmp) {
        features::TargetFileWriter w(tmp, dtype, shape, meta);
        w.append(data);
        w.finish();
      });
      log.str("");
      const FeatureTargets t = features::load_or_compute_targets(sc, vgg(), opts);
      CHECK_FALSE(t.from_cache);
      const std::string why[] = {"holds key '0123456789abcdef'", other_text, "recomputing", "targets are F32, expected F16"};
      CHECK(log.str().find(why[variant]) != std::string::npos);
      CHECK(features::maps_to_host(t) == want);
    }
  }
  SUBCASE("flipped bytes fail the checksum and are recomputed") {
    {
      std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
      f.seekp(std::streamoff(fs::file_size(path) - 100));
      f.write("\x7f\x7f\x7f\x7f", 4);
    }
    log.str("");
    const FeatureTargets t = features::load_or_compute_targets(sc, vgg(), opts);
    CHECK_FALSE(t.from_cache);
    CHECK(log.str().find("checksum") != std::string::npos);
  }
  SUBCASE("the key follows the pixels, the images' names and the scene root") {
    scene::Scene other = sc;
    CHECK(features::target_cache_key(other, vgg()) == first.key);
    other.train[3].rgb[100] += 0.01f;  // e.g. another downsample or background: other pixels
    CHECK(features::target_cache_key(other, vgg()) != first.key);
    other = sc;
    other.train[3].image_path += "x";
    CHECK(features::target_cache_key(other, vgg()) != first.key);
    other = sc;
    other.root = sc.root + "/elsewhere";
    CHECK(features::target_cache_key(other, vgg()) != first.key);
  }
  SUBCASE("use_cache = false neither reads nor writes") {
    features::TargetCacheOptions off = opts;
    off.use_cache = false;
    off.dir = (work_dir() / "cache-off").string();
    const FeatureTargets t = features::load_or_compute_targets(sc, vgg(), off);
    CHECK_FALSE(t.from_cache);
    CHECK_FALSE(fs::exists(off.dir));
  }
}

TEST_CASE("targets cache: default folder under STYLERF_CACHE_DIR; bad inputs name what is wrong") {
  const char* old = std::getenv("STYLERF_CACHE_DIR");
  const std::string saved = old ? old : "";
  setenv("STYLERF_CACHE_DIR", "/some/cache", 1);
  CHECK(features::default_target_cache_dir() == "/some/cache/targets");
  if (old)
    setenv("STYLERF_CACHE_DIR", saved.c_str(), 1);
  else
    unsetenv("STYLERF_CACHE_DIR");

  nn::VggEncoder empty;
  scene::Scene s = memory_scene(16, 16, 2, 1);
  testing::expect_error([&] { features::load_or_compute_targets(s, empty, {}); }, "no weights loaded");
  features::TargetCacheOptions off;
  off.use_cache = false;
  s.train[1].rgb.clear();
  testing::expect_error([&] { features::load_or_compute_targets(s, vgg(), off); }, "r_1.png has no pixels loaded");
  scene::Scene none;
  none.name = "empty";
  testing::expect_error([&] { features::load_or_compute_targets(none, vgg(), off); }, "has no training views");
}

TEST_CASE("targets of views smaller than 8 pixels") {
  const scene::Scene s = memory_scene(5, 3, 2, 7);
  features::TargetCacheOptions opts;
  opts.dir = (work_dir() / "cache-tiny").string();
  const FeatureTargets t = features::load_or_compute_targets(s, vgg(), opts);
  CHECK(t.maps.shape() == host::Shape{2, 1, 2, 256});
  const std::vector<float> v = features::maps_to_host(t);
  CHECK(testing::all_finite(v));
  CHECK(*std::max_element(v.begin(), v.end()) > 0.0f);
  CHECK(features::load_or_compute_targets(s, vgg(), opts).from_cache);
}

TEST_CASE("gather_targets forward against a double reference (F.interpolate, align_corners=False)") {
  for (auto [V, hf, wf, C, R] : {std::array<int, 5>{3, 5, 7, 16, 301}, std::array<int, 5>{2, 4, 6, 256, 200},
                                 std::array<int, 5>{2, 1, 1, 8, 40}}) {
    for (host::DType dtype : {host::DType::F32, host::DType::F16}) {
      CAPTURE(C);
      CAPTURE(hf);
      CAPTURE(host::dtype_name(dtype));
      GatherCase g = make_case(V, hf, wf, C, R, 11 + uint64_t(C));
      if (dtype == host::DType::F16) g = half_rounded(g);
      const Tensor out = features::gather_targets(device_maps(g, dtype), view_tensor(g.view),
                                                  Tensor::from_host(g.xy, {R, 2}));
      CHECK(out.shape() == host::Shape{R, C});
      testing::check_close(out.to_host(), ref_gather(testing::to_double(g.maps), hf, wf, C, g.view, g.xy), 1e-5,
                           1e-5, "gather_targets");
    }
  }
  // All pixel centres of a whole 4-aligned image: exactly F.interpolate(size=(4 hf, 4 wf)).
  const int hf = 3, wf = 4, C = 8;
  GatherCase g = make_case(1, hf, wf, C, 1, 3);
  g.view.clear();
  g.xy.clear();
  for (int y = 0; y < 4 * hf; ++y)
    for (int x = 0; x < 4 * wf; ++x) g.view.push_back(0), g.xy.push_back(x + 0.5f), g.xy.push_back(y + 0.5f);
  const int R = int(g.view.size());
  const std::vector<float> full =
      features::gather_targets(device_maps(g), view_tensor(g.view), Tensor::from_host(g.xy, {R, 2}))
          .to_host();
  testing::check_close(full, ref_gather(testing::to_double(g.maps), hf, wf, C, g.view, g.xy), 1e-6, 1e-6, "full image");
  // The centre of map pixel (i, j) is image position (4j + 2, 4i + 2): the map value itself, bit for bit.
  std::vector<int32_t> v0{0};
  std::vector<float> at{4 * 2 + 2.0f, 4 * 1 + 2.0f};
  const std::vector<float> centre =
      features::gather_targets(device_maps(g), view_tensor(v0), Tensor::from_host(at, {1, 2})).to_host();
  for (int c = 0; c < C; ++c) CHECK(centre[size_t(c)] == g.maps[(size_t(1) * wf + 2) * C + c]);
}

TEST_CASE("gather_targets: a bad view index or position gives NaN, not another pixel; shape errors") {
  GatherCase g = make_case(2, 3, 3, 8, 4, 5);
  g.view = {0, 2, -1, 1};
  g.xy[6] = NAN;
  const std::vector<float> out = features::gather_targets(device_maps(g), view_tensor(g.view),
                                                          Tensor::from_host(g.xy, {4, 2}))
                                     .to_host();
  for (int c = 0; c < 8; ++c) {
    CHECK(std::isfinite(out[size_t(c)]));
    CHECK(std::isnan(out[8 + size_t(c)]));
    CHECK(std::isnan(out[16 + size_t(c)]));
    CHECK(std::isnan(out[24 + size_t(c)]));
  }
  const Tensor idx = view_tensor(g.view), xy = Tensor::from_host(g.xy, {4, 2});
  testing::expect_error([&] { features::gather_targets(Tensor::zeros({2, 3, 3, 12}), idx, xy); }, "multiple of 8");
  testing::expect_error([&] { features::gather_targets(Tensor::zeros({2, 3, 24}), idx, xy); }, "[V, Hf, Wf, C]");
  testing::expect_error([&] { features::gather_targets(device_maps(g), idx, Tensor::zeros({4, 3})); }, "pixel_xy");
  Tensor dmaps = Tensor::zeros({2, 3, 3, 8});
  testing::expect_error([&] { features::gather_targets_backward(idx, xy, Tensor::zeros({4, 16}), dmaps); }, "dout");
  // Rays marked NaN in the forward add nothing in the backward.
  features::gather_targets_backward(idx, xy, Tensor::full({4, 8}, 1.0f), dmaps);
  const std::vector<float> d = dmaps.to_host();
  double total = 0;
  for (float x : d) total += x;
  CHECK(total == doctest::Approx(8.0));  // ray 0 only: 8 channels, weights summing to 1
}

TEST_CASE("gather_targets backward against central finite differences of the reference") {
  for (int C : {8, 16}) {
    CAPTURE(C);
    const GatherCase g = make_case(3, 4, 5, C, 157, 21 + uint64_t(C));
    const int R = g.R;
    const std::vector<float> gout = testing::random_normal(size_t(R) * C, 31);
    const std::vector<double> gd = testing::to_double(gout);
    auto loss = [&](const std::vector<double>& maps) {
      return testing::dot(gd, ref_gather(maps, g.hf, g.wf, C, g.view, g.xy));
    };
    const std::vector<double> fd = testing::finite_difference(loss, testing::to_double(g.maps), 1e-3);
    // Accumulates: start from a known non-zero gradient.
    const std::vector<float> start = testing::random_normal(g.maps.size(), 41);
    Tensor dmaps = Tensor::from_host(start, {g.V, g.hf, g.wf, C});
    features::gather_targets_backward(view_tensor(g.view), Tensor::from_host(g.xy, {R, 2}),
                                      Tensor::from_host(gout, {R, C}), dmaps);
    std::vector<double> want(fd.size());
    for (size_t i = 0; i < fd.size(); ++i) want[i] = fd[i] + start[i];
    testing::check_close(dmaps.to_host(), want, 1e-4, 1e-4, "gather_targets_backward");
  }
}

TEST_CASE("target_patch: exact crop at scale 4, reference bilinear at scales 1 and 2, bounds checked") {
  const int V = 2, hf = 6, wf = 9, C = 16;
  for (host::DType dtype : {host::DType::F32, host::DType::F16}) {
    CAPTURE(host::dtype_name(dtype));
    GatherCase g = make_case(V, hf, wf, C, 1, 51);
    if (dtype == host::DType::F16) g = half_rounded(g);
    FeatureTargets t;
    t.maps = device_maps(g, dtype);
    t.image_width = 4 * wf - 2;  // 34 x 22: not multiples of 4
    t.image_height = 4 * hf - 2;
    // Scale 4 at an aligned corner: the stored map, bit for bit.
    const std::vector<float> crop = features::target_patch(t, 1, 8, 4, 24, 16, 4).to_host();
    REQUIRE(crop.size() == size_t(C) * 4 * 6);
    bool exact = true;
    for (int c = 0; c < C; ++c)
      for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 6; ++j)
          exact &= crop[(size_t(c) * 4 + i) * 6 + j] == g.maps[((size_t(1) * hf + 1 + i) * wf + 2 + j) * C + c];
    CHECK(exact);
    for (auto [scale, x0, y0, w, h] : {std::array<int, 5>{1, 3, 5, 31, 17}, std::array<int, 5>{2, 0, 2, 34, 20},
                                       std::array<int, 5>{4, 2, 2, 32, 20}}) {
      CAPTURE(scale);
      const int ho = h / scale, wo = w / scale;
      std::vector<int32_t> view;
      std::vector<float> xy;
      for (int i = 0; i < ho; ++i)
        for (int j = 0; j < wo; ++j)
          view.push_back(0), xy.push_back(x0 + scale * (j + 0.5f)), xy.push_back(y0 + scale * (i + 0.5f));
      const std::vector<double> rows = ref_gather(testing::to_double(g.maps), hf, wf, C, view, xy);
      std::vector<double> want(rows.size());
      for (int p = 0; p < ho * wo; ++p)
        for (int c = 0; c < C; ++c) want[size_t(c) * ho * wo + p] = rows[size_t(p) * C + c];
      const Tensor out = features::target_patch(t, 0, x0, y0, w, h, scale);
      CHECK(out.shape() == host::Shape{1, C, ho, wo});
      testing::check_close(out.to_host(), want, 1e-5, 1e-5, "target_patch");
    }
    testing::expect_error([&] { features::target_patch(t, 0, 4, 0, 32, 8, 4); }, "inside the 34x22 image");
    testing::expect_error([&] { features::target_patch(t, 0, 0, 0, 30, 8, 4); }, "must divide");
    testing::expect_error([&] { features::target_patch(t, 0, 0, 0, 8, 8, 3); }, "scale must be 1, 2 or 4");
    testing::expect_error([&] { features::target_patch(t, 2, 0, 0, 8, 8, 4); }, "there are 2 training views");
  }
}

TEST_CASE("FeatureRaySampler: the density stage's rays plus each ray's view and pixel centre") {
  const scene::Scene& sc = generated_scene();
  features::FeatureRaySampler a(sc, 17), b(sc, 17);
  const features::FeatureRays r = a.next(500);
  REQUIRE(r.size() == 500);
  REQUIRE(r.rays.size() == 500);
  CHECK(b.next(500).pixel_xy == r.pixel_xy);  // deterministic for a seed
  const int W = sc.width();
  std::vector<bool> seen(sc.train.size(), false);
  for (size_t i = 0; i < r.size(); ++i) {
    const int v = r.view[i];
    REQUIRE(v >= 0);
    REQUIRE(v < int(sc.train.size()));
    seen[size_t(v)] = true;
    const int x = int(r.pixel_xy[2 * i]), y = int(r.pixel_xy[2 * i + 1]);
    CHECK(r.pixel_xy[2 * i] == x + 0.5f);
    CHECK(r.rays.pixel[i] == v * W * sc.height() + y * W + x);
    const scene::Rays cam = scene::camera_rays(sc, sc.train[size_t(v)].camera);
    const size_t p = size_t(y) * W + x;
    for (int k = 0; k < 3; ++k) {
      CHECK(r.rays.origins[3 * i + size_t(k)] == cam.origins[3 * p + size_t(k)]);
      CHECK(r.rays.directions[3 * i + size_t(k)] == cam.directions[3 * p + size_t(k)]);
      CHECK(r.rays.rgb[3 * i + size_t(k)] == sc.train[size_t(v)].rgb[3 * p + size_t(k)]);
    }
  }
  CHECK(std::count(seen.begin(), seen.end(), true) == int(sc.train.size()));
  CHECK(r.view_tensor().shape() == host::Shape{500});
  CHECK(r.pixel_xy_tensor().shape() == host::Shape{500, 2});
  testing::expect_error([&] { a.next(0); }, "batch must be at least 1");
}

TEST_CASE("targets gathered at sampled rays, end to end on the generated scene") {
  const scene::Scene& sc = generated_scene();
  features::TargetCacheOptions opts;
  opts.dir = (work_dir() / "cache").string();
  const FeatureTargets t = features::load_or_compute_targets(sc, vgg(), opts);
  features::FeatureRaySampler s(sc, 5);
  const features::FeatureRays r = s.next(256);
  const std::vector<float> got = features::gather_targets(t.maps, r.view_tensor(), r.pixel_xy_tensor()).to_host();
  testing::check_close(got, ref_gather(testing::to_double(features::maps_to_host(t)), t.map_height(), t.map_width(), 256,
                                       r.view, r.pixel_xy),
                       1e-5, 1e-4, "sampled targets");
}

TEST_CASE("PatchSampler: patches larger than the image, 4-aligned corners, rays per pixel or per 4x4 block") {
  const scene::Scene& sc = generated_scene();  // S x S: 40, or 24 under STYLERF_TEST_SMALL
  const int S = kSceneSize;
  features::PatchSampler big(sc, 3, 256);
  CHECK(big.width() == S);
  CHECK(big.height() == S);
  const features::Patch whole = big.next();
  CHECK(whole.x0 == 0);
  CHECK(whole.y0 == 0);
  CHECK(whole.rgb_tensor().shape() == host::Shape{1, 3, S, S});
  const scene::Rays cam = scene::camera_rays(sc, sc.train[size_t(whole.view)].camera);
  CHECK(whole.rays.origins == cam.origins);
  CHECK(whole.rays.directions == cam.directions);

  features::PatchSampler small(sc, 4, 16);
  bool moved = false;
  for (int k = 0; k < 20; ++k) {
    const features::Patch p = small.next(k % 2 ? 4 : 1);
    CAPTURE(p.x0);
    CAPTURE(p.y0);
    CHECK(p.width == 16);
    CHECK(p.x0 % 4 == 0);
    CHECK(p.y0 % 4 == 0);
    CHECK(p.x0 + 16 <= S);
    CHECK(p.y0 + 16 <= S);
    moved |= p.x0 != 0 || p.y0 != 0;
    const scene::View& v = sc.train[size_t(p.view)];
    for (int c = 0; c < 3; ++c)
      CHECK(p.rgb[(size_t(c) * 16 + 5) * 16 + 7] == v.rgb[(size_t(p.y0 + 5) * S + p.x0 + 7) * 3 + size_t(c)]);
    const int n = 16 / p.stride;
    REQUIRE(p.rays.size() == size_t(n) * n);
    CHECK(p.rays.rgb.size() == (p.stride == 1 ? 3 * size_t(n) * n : 0));
    // Each ray projects back to the centre of its block (row-major order).
    for (int i = 0; i < n; i += 3)
      for (int j = 0; j < n; j += 2) {
        const size_t r = size_t(i) * n + j;
        std::array<float, 3> q;
        for (size_t a = 0; a < 3; ++a) q[a] = p.rays.origins[3 * r + a] + 3.0f * p.rays.directions[3 * r + a];
        float px = 0, py = 0;
        REQUIRE(v.camera.project(q, px, py));
        CHECK(px == doctest::Approx(p.x0 + p.stride * (j + 0.5)).epsilon(1e-4));
        CHECK(py == doctest::Approx(p.y0 + p.stride * (i + 0.5)).epsilon(1e-4));
      }
  }
  CHECK(moved);

  // Not a multiple of 8: the whole image cropped to one (44 x 37 -> 40 x 32).
  const scene::Scene odd = memory_scene(44, 37, 2, 3);
  features::PatchSampler crop(odd, 1, 256);
  CHECK(crop.width() == 40);
  CHECK(crop.height() == 32);
  const features::Patch p = crop.at(1, 4, 4, 4);
  CHECK(p.rays.size() == 10 * 8);
  testing::expect_error([&] { crop.at(1, 8, 0); }, "inside the 44x37 image");
  testing::expect_error([&] { crop.at(1, 2, 0); }, "multiple of 4");
  testing::expect_error([&] { crop.next(3); }, "stride must be 1, 2 or 4");
  const scene::Scene tiny = memory_scene(5, 9, 1, 3);
  testing::expect_error([&] { features::PatchSampler(tiny, 1, 256); }, "at least 8x8 pixels");
  testing::expect_error([&] { features::PatchSampler(odd, 1, 100); }, "multiple of 8");
}
