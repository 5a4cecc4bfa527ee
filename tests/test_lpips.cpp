// LPIPS (VGG-16, v0.1 heads): the distance-map kernel against a double-precision reference (zero
// features, huge and tiny magnitudes, odd channel counts, 1x1 maps) and its backward against central
// differences; the whole metric against a double CPU reference built from the weights file and against
// the official values in ../shared/reference/lpips (lpips 0.1.4); properties that need no shared data
// (identity, symmetry, the mask, odd sizes, refused sizes).
//
// The weights come from the set-up command `bash scripts/fetch_weights.sh`; without them these tests FAIL
// (they do not skip) with a message naming that command.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "host/error.hpp"
#include "host/files.hpp"
#include "lib/eval/lpips.hpp"
#include "lib/eval/lpips_map.hpp"
#include "lib/io/image.hpp"
#include "lib/nn/weights.hpp"
#include "tests/conv_reference.hpp"
#include "tests/testing.hpp"

namespace fs = std::filesystem;
using namespace stylerf;
using host::Tensor;
using testing::check_close;
using testing::RefTensor;

namespace {

// ---- double reference of the per-tap map ------------------------------------------------------------

// a, b [C][HW] -> d [HW], straight from the definition (double: 1e30^2 does not overflow).
std::vector<double> ref_map(const std::vector<double>& a, const std::vector<double>& b, const std::vector<double>& w,
                            int C, int HW) {
  std::vector<double> d(HW, 0.0);
  for (int p = 0; p < HW; ++p) {
    double na = 0, nb = 0;
    for (int c = 0; c < C; ++c) {
      na += a[size_t(c) * HW + p] * a[size_t(c) * HW + p];
      nb += b[size_t(c) * HW + p] * b[size_t(c) * HW + p];
    }
    na = std::sqrt(na) + double(eval::kLpipsEps);
    nb = std::sqrt(nb) + double(eval::kLpipsEps);
    for (int c = 0; c < C; ++c) {
      const double diff = a[size_t(c) * HW + p] / na - b[size_t(c) * HW + p] / nb;
      d[p] += w[c] * diff * diff;
    }
  }
  return d;
}

std::vector<double> d(const std::vector<float>& v) { return testing::to_double(v); }

std::vector<float> run_map(const std::vector<float>& a, const std::vector<float>& b, const std::vector<float>& w, int C,
                           int H, int W) {
  return eval::lpips_distance_map(Tensor::from_host(a, {1, C, H, W}), Tensor::from_host(b, {1, C, H, W}),
                                  Tensor::from_host(w, {C}))
      .to_host();
}

// ---- weights ----------------------------------------------------------------------------------------

std::string lpips_path() { return nn::weights_path(eval::kLpipsVggWeightsFile); }

// Fails the test (never skips) when the set-up step has not been run.
void require_weights() {
  REQUIRE_MESSAGE(fs::exists(lpips_path()), "LPIPS weights missing: " << lpips_path() << " — run `"
                                                                      << std::string(nn::kFetchWeightsCommand)
                                                                      << "` first (weights folder: $STYLERF_WEIGHTS, "
                                                                         "default ~/.cache/stylerf/weights)");
}

const eval::Lpips& lpips() {
  static eval::Lpips l = eval::Lpips::load_default();
  return l;
}

// ---- a double CPU reference of the whole metric, independent of lib/eval/lpips.cpp ---------------------

RefTensor ref_pool(const RefTensor& x) {  // floor for odd sizes
  RefTensor y{x.C, x.H / 2, x.W / 2, std::vector<double>(size_t(x.C) * (x.H / 2) * (x.W / 2))};
  for (int c = 0; c < x.C; ++c)
    for (int yy = 0; yy < y.H; ++yy)
      for (int xx = 0; xx < y.W; ++xx)
        y.at(c, yy, xx) = std::max(std::max(x.at(c, 2 * yy, 2 * xx), x.at(c, 2 * yy, 2 * xx + 1)),
                                   std::max(x.at(c, 2 * yy + 1, 2 * xx), x.at(c, 2 * yy + 1, 2 * xx + 1)));
  return y;
}

std::vector<RefTensor> ref_taps(const io::Image& im) {
  const auto st = nn::load_weights(lpips_path());
  const double shift[3] = {-0.030, -0.088, -0.188}, scale[3] = {0.458, 0.448, 0.450};
  RefTensor h{3, im.height, im.width, std::vector<double>(im.data.size())};
  for (int c = 0; c < 3; ++c)
    for (int y = 0; y < im.height; ++y)
      for (int x = 0; x < im.width; ++x) h.at(c, y, x) = (2.0 * im.at(c, y, x) - 1.0 - shift[c]) / scale[c];
  // cfg [64, 64, M, 128, 128, M, 256, 256, 256, M, 512, 512, 512, M, 512, 512, 512]; tap before each M and at the end
  const int cfg[] = {64, 64, 0, 128, 128, 0, 256, 256, 256, 0, 512, 512, 512, 0, 512, 512, 512};
  std::vector<RefTensor> taps;
  int conv = 0;
  for (int v : cfg) {
    if (v == 0) {
      taps.push_back(h);
      h = ref_pool(h);
      continue;
    }
    const std::string key = "trunk." + std::to_string(conv++);
    h = testing::ref_conv(h, st.get(key + ".weight").data, st.get(key + ".bias").data, v, 3, false);
    testing::ref_relu(h);
  }
  taps.push_back(h);
  return taps;
}

double ref_lpips(const io::Image& a, const io::Image& b) {
  const auto st = nn::load_weights(lpips_path());
  const auto ta = ref_taps(a), tb = ref_taps(b);
  double total = 0;
  for (int l = 0; l < 5; ++l) {
    const int hw = ta[l].H * ta[l].W;
    const auto dm = ref_map(ta[l].v, tb[l].v, d(st.get("lin." + std::to_string(l) + ".weight").data), ta[l].C, hw);
    double s = 0;
    for (double v : dm) s += v;
    total += s / hw;
  }
  return total;
}

// ---- images -------------------------------------------------------------------------------------------

// A smooth colourful pattern with some texture, reproducible from the seed.
io::Image pattern(int w, int h, uint64_t seed) {
  io::Image im{w, h, std::vector<float>(size_t(3) * w * h)};
  const auto noise = testing::random_uniform(im.data.size(), seed, -0.1f, 0.1f);
  const float f = 0.05f + 0.02f * float(seed % 5);
  for (int c = 0; c < 3; ++c)
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const size_t i = (size_t(c) * h + y) * w + x;
        const float v = 0.5f + 0.3f * std::sin(f * x * (c + 1) + 0.7f * c) * std::cos(f * 1.3f * y + 0.3f * seed);
        im.data[i] = std::min(1.0f, std::max(0.0f, v + noise[i]));
      }
  return im;
}

}  // namespace

// ---- the distance-map kernel --------------------------------------------------------------------------

TEST_CASE("lpips map: forward matches the double reference (odd C, odd map sizes)") {
  for (int C : {1, 3, 37, 512}) {
    for (auto hw : {std::array<int, 2>{1, 1}, std::array<int, 2>{5, 7}, std::array<int, 2>{16, 16}}) {
      CAPTURE(C);
      CAPTURE(hw[0]);
      CAPTURE(hw[1]);
      const int n = C * hw[0] * hw[1];
      // Post-ReLU features are >= 0; signed ones exercise the norm too.
      auto a = testing::random_normal(n, 100 + C, 2.0f), b = testing::random_normal(n, 200 + C, 2.0f);
      auto w = testing::random_uniform(C, 300 + C, 0.0f, 0.2f);
      // float sums of C terms <= w_c * 4: relative 1e-5 of the value plus 1e-6 absolute.
      check_close(run_map(a, b, w, C, hw[0], hw[1]), ref_map(d(a), d(b), d(w), C, hw[0] * hw[1]), 1e-5, 1e-6, "map");
    }
  }
}

TEST_CASE("lpips map: zero positions, huge and tiny magnitudes stay finite and exact") {
  const int C = 19, H = 2, W = 5, HW = H * W;
  auto a = testing::random_uniform(C * HW, 1, 0.0f, 1.0f), b = testing::random_uniform(C * HW, 2, 0.0f, 1.0f);
  auto w = testing::random_uniform(C, 3, 0.0f, 0.3f);
  auto scale_pos = [&](std::vector<float>& v, int p, float s) {
    for (int c = 0; c < C; ++c) v[size_t(c) * HW + p] *= s;
  };
  scale_pos(a, 0, 0.0f);  // a all zero: u = 0, d = sum w v^2
  scale_pos(a, 1, 0.0f);  // both all zero: d = 0
  scale_pos(b, 1, 0.0f);
  scale_pos(a, 2, 1e18f);  // squares 1e36: the plain sum over 19 channels is still finite
  scale_pos(b, 2, 3e18f);
  scale_pos(a, 3, 1e37f);  // squares overflow: the rescaled sum
  scale_pos(b, 3, 1e-3f);
  scale_pos(a, 4, 1e-30f);  // ||a|| << eps: u ~ a / eps
  scale_pos(b, 4, 1e-12f);
  scale_pos(a, 5, 1e-41f);  // denormal features
  scale_pos(b, 6, 1e30f);
  a[size_t(7) * HW + 7] = 5e37f;  // one huge channel among ordinary ones
  const auto got = run_map(a, b, w, C, H, W);
  REQUIRE(testing::all_finite(got));
  const auto want = ref_map(d(a), d(b), d(w), C, HW);
  check_close(got, want, 1e-5, 1e-7, "map with extreme positions");
  CHECK(got[1] == 0.0f);
  // Identical features give exactly 0 at every position, whatever their magnitude.
  const auto same = run_map(a, a, w, C, H, W);
  for (float v : same) CHECK(v == 0.0f);
}

TEST_CASE("lpips map: 1e18 features over 512 channels (sum of squares past FLT_MAX)") {
  const int C = 512, H = 1, W = 11, HW = H * W;  // one group of 8 positions and a tail of 3
  auto a = testing::random_uniform(C * HW, 31, 2e18f, 3e18f), b = testing::random_uniform(C * HW, 32, 0.0f, 3e18f);
  for (int c = 0; c < C; ++c) b[size_t(c) * HW + 9] = 1e-20f;  // next to a lane that needs rescaling
  auto w = testing::random_uniform(C, 33, 0.0f, 0.01f);
  const auto got = run_map(a, b, w, C, H, W);
  REQUIRE(testing::all_finite(got));
  check_close(got, ref_map(d(a), d(b), d(w), C, HW), 1e-5, 1e-7, "map of 1e18 features");
}

TEST_CASE("lpips map: backward matches central differences") {
  const int C = 11, H = 3, W = 4, HW = H * W;
  auto a = testing::random_normal(C * HW, 11), b = testing::random_normal(C * HW, 12);
  auto w = testing::random_uniform(C, 13, 0.05f, 0.3f);
  auto g = testing::random_normal(HW, 14);
  Tensor ta = Tensor::from_host(a, {1, C, H, W}), tb = Tensor::from_host(b, {1, C, H, W});
  const auto da = eval::lpips_distance_map_backward(ta, tb, Tensor::from_host(w, {C}), Tensor::from_host(g, {HW}));
  CHECK(da.shape() == host::Shape{1, C, H, W});
  const auto bd = d(b), wd = d(w), gd = d(g);
  auto f = [&](const std::vector<double>& x) { return testing::dot(gd, ref_map(x, bd, wd, C, HW)); };
  // Smooth away from the zero vector: central differences (h = 1e-4) are good to ~1e-8; float kernel 1e-4.
  check_close(da.to_host(), testing::finite_difference(f, d(a), 1e-4), 1e-4, 1e-5, "lpips map backward");
}

TEST_CASE("lpips map: backward at zero, huge and tiny positions") {
  const int C = 7, H = 1, W = 4, HW = H * W;
  auto a = testing::random_uniform(C * HW, 21, 0.1f, 1.0f), b = testing::random_uniform(C * HW, 22, 0.1f, 1.0f);
  auto w = testing::random_uniform(C, 23, 0.05f, 0.3f);
  auto g = testing::random_normal(HW, 24);
  for (int c = 0; c < C; ++c) {
    a[size_t(c) * HW + 0] = 0.0f;    // u = a / eps near 0: da = r / eps with r = 2 g w (0 - v)
    a[size_t(c) * HW + 1] *= 1e20f;  // da ~ 1e-20
    a[size_t(c) * HW + 2] *= 1e-3f;  // small but >> eps: the ordinary formula
  }
  const auto da = eval::lpips_distance_map_backward(Tensor::from_host(a, {1, C, H, W}), Tensor::from_host(b, {1, C, H, W}),
                                                    Tensor::from_host(w, {C}), Tensor::from_host(g, {HW}))
                      .to_host();
  REQUIRE(testing::all_finite(da));
  // Analytic reference in double: da_k = (r_k - a^_k sum_c r_c u_c) / (||a|| + eps).
  std::vector<double> want(da.size());
  for (int p = 0; p < HW; ++p) {
    double na = 0, nb = 0;
    for (int c = 0; c < C; ++c) {
      na += double(a[size_t(c) * HW + p]) * a[size_t(c) * HW + p];
      nb += double(b[size_t(c) * HW + p]) * b[size_t(c) * HW + p];
    }
    na = std::sqrt(na), nb = std::sqrt(nb);
    const double Da = na + eval::kLpipsEps, Db = nb + eval::kLpipsEps;
    std::vector<double> r(C), u(C);
    double dot = 0;
    for (int c = 0; c < C; ++c) {
      u[c] = a[size_t(c) * HW + p] / Da;
      r[c] = 2.0 * g[p] * w[c] * (u[c] - b[size_t(c) * HW + p] / Db);
      dot += r[c] * u[c];
    }
    for (int c = 0; c < C; ++c) {
      const double hat = na > 0 ? a[size_t(c) * HW + p] / na : 0.0;
      want[size_t(c) * HW + p] = (r[c] - hat * dot) / Da;
    }
  }
  // Per position, the scale of the gradient differs by 40 orders of magnitude: compare each relative to
  // its own position's largest entry.
  for (int p = 0; p < HW; ++p) {
    CAPTURE(p);
    double mx = 0;
    for (int c = 0; c < C; ++c) mx = std::max(mx, std::fabs(want[size_t(c) * HW + p]));
    for (int c = 0; c < C; ++c)
      CHECK(std::fabs(da[size_t(c) * HW + p] - want[size_t(c) * HW + p]) <= 1e-4 * mx);
  }
}

TEST_CASE("lpips map: bad shapes give clear errors") {
  testing::expect_error([] { eval::lpips_distance_map(Tensor::zeros({1, 4, 2, 2}), Tensor::zeros({1, 4, 2, 3}), Tensor::zeros({4})); },
                        "fb");
  testing::expect_error([] { eval::lpips_distance_map(Tensor::zeros({1, 4, 2, 2}), Tensor::zeros({1, 4, 2, 2}), Tensor::zeros({3})); },
                        "w (one weight per channel)");
  testing::expect_error([] { eval::lpips_distance_map(Tensor::zeros({2, 4, 2, 2}), Tensor::zeros({2, 4, 2, 2}), Tensor::zeros({4})); },
                        "[1,C,H,W]");
}

// ---- the whole metric ---------------------------------------------------------------------------------

TEST_CASE("lpips: the weights are installed (set-up: bash scripts/fetch_weights.sh)") {
  require_weights();
  const auto st = nn::load_weights(lpips_path());
  CHECK(st.get("trunk.0.weight").shape == std::vector<int64_t>{64, 3, 3, 3});
  CHECK(st.get("trunk.12.weight").shape == std::vector<int64_t>{512, 512, 3, 3});
  CHECK(st.get("lin.4.weight").shape == std::vector<int64_t>{512});
  CHECK(lpips().loaded());
}

TEST_CASE("lpips: matches a double-precision CPU reference (odd sizes floor at every pool)") {
  require_weights();
  const io::Image a = pattern(21, 18, 1), b = pattern(21, 18, 2);  // taps 18x21, 9x10, 4x5, 2x2, 1x1
  const double got = lpips().distance(a, b), want = ref_lpips(a, b);
  INFO("ours " << got << ", reference " << want);
  CHECK(std::fabs(got - want) <= 1e-5 + 1e-4 * want);
}

TEST_CASE("lpips: the official values of ../shared/reference/lpips (lpips 0.1.4, VGG)") {
  require_weights();
  const std::string dir = testing::shared_reference_dir("lpips");
  if (dir.empty()) {
    MESSAGE("../shared/reference/lpips is absent (no ../shared on this machine, or STYLERF_TEST_DATA unset): the "
            "comparison with the official lpips values is not run; the other LPIPS tests still are");
    return;
  }
  const auto j = nlohmann::json::parse(host::read_file(dir + "/pairs.json"));
  REQUIRE(j["pairs"].size() == 6);
  for (const auto& pair : j["pairs"]) {
    const std::string fa = pair["a"], fb = pair["b"];
    const double want = pair["lpips_vgg"];
    const double got = lpips().distance(io::load_image(dir + "/" + fa), io::load_image(dir + "/" + fb));
    MESSAGE(std::setprecision(7) << fa << " vs " << fb << ": ours " << got << ", official " << want << ", |diff| " << std::fabs(got - want));
    CHECK(std::fabs(got - want) <= 1e-3);
  }
}

TEST_CASE("lpips: identity, symmetry, and a larger difference for a larger change") {
  require_weights();
  const io::Image a = pattern(64, 48, 3), b = pattern(64, 48, 4);
  CHECK(lpips().distance(a, a) == 0.0);
  const double ab = lpips().distance(a, b), ba = lpips().distance(b, a);
  CHECK(ab > 0.0);
  CHECK(ab == doctest::Approx(ba).epsilon(1e-6));
  io::Image slightly = a;
  const auto noise = testing::random_uniform(a.data.size(), 5, -0.02f, 0.02f);
  for (size_t i = 0; i < a.data.size(); ++i) slightly.data[i] = std::min(1.0f, std::max(0.0f, a.data[i] + noise[i]));
  const double small = lpips().distance(a, slightly);
  CHECK(small > 0.0);
  CHECK(small < ab);
}

TEST_CASE("lpips: masked distance") {
  require_weights();
  const int W = 96, H = 48;
  const io::Image a = pattern(W, H, 6);
  const std::vector<float> ones(size_t(W) * H, 1.0f);
  const io::Image other = pattern(W, H, 7);
  CHECK(lpips().distance(a, other, ones) == doctest::Approx(lpips().distance(a, other)).epsilon(1e-12));

  SUBCASE("the definition: taps weighted by the mask's area average over each position's block") {
    auto mask = testing::random_uniform(size_t(W) * H, 8, 0.0f, 1.0f);
    const auto maps = lpips().distance_maps(io::to_tensor(a), io::to_tensor(other));
    const auto sizes = eval::Lpips::tap_sizes(H, W);
    double want = 0;
    for (int l = 0; l < 5; ++l) {
      const int s = 1 << l, h = sizes[l][0], w = sizes[l][1];
      const auto dm = maps[l].to_host();
      REQUIRE(dm.size() == size_t(h) * w);
      double num = 0, den = 0;
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
          double m = 0;  // mean over the 2^l x 2^l input block, computed directly
          for (int yy = y * s; yy < (y + 1) * s; ++yy)
            for (int xx = x * s; xx < (x + 1) * s; ++xx) m += mask[size_t(yy) * W + xx];
          m /= double(s) * s;
          num += m * dm[size_t(y) * w + x];
          den += m;
        }
      want += num / den;
    }
    CHECK(lpips().distance(a, other, mask) == doctest::Approx(want).epsilon(1e-9));
  }
  SUBCASE("differences where the mask is 0 are (almost) ignored") {
    // Mask: the left third. b = a with noise in the right third (32 px away from the masked-in region).
    std::vector<float> mask(size_t(W) * H, 0.0f);
    io::Image b = a;
    const auto noise = testing::random_uniform(a.data.size(), 9, 0.0f, 1.0f);
    for (int c = 0; c < 3; ++c)
      for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
          if (c == 0 && x < W / 3) mask[size_t(y) * W + x] = 1.0f;
          const size_t i = (size_t(c) * H + y) * W + x;
          if (x >= 2 * W / 3) b.data[i] = noise[i];
        }
    const double unmasked = lpips().distance(a, b), masked = lpips().distance(a, b, mask);
    INFO("unmasked " << unmasked << ", masked " << masked);
    CHECK(unmasked > 0.05);
    // Only the deep taps (receptive fields of 100-196 px) see the noise from inside the mask: masked is
    // about 1/75 of unmasked here.
    CHECK(masked < 0.05 * unmasked);
    // The same noise inside the mask counts fully.
    io::Image inside = a;
    for (int c = 0; c < 3; ++c)
      for (int y = 0; y < H; ++y)
        for (int x = 0; x < W / 3; ++x) inside.data[(size_t(c) * H + y) * W + x] = noise[(size_t(c) * H + y) * W + x];
    CHECK(lpips().distance(a, inside, mask) > 4.0 * masked);
  }
  SUBCASE("an all-zero mask gives 0; bad masks are refused") {
    CHECK(lpips().distance(a, other, std::vector<float>(size_t(W) * H, 0.0f)) == 0.0);
    testing::expect_error([&] { lpips().distance(a, other, std::vector<float>(10, 1.0f)); }, "the mask has 10 values");
    auto bad = ones;
    bad[W + 3] = 1.5f;
    testing::expect_error([&] { lpips().distance(a, other, bad); }, "pixel 3,1 is outside [0, 1]");
  }
}

TEST_CASE("lpips: odd sizes run, too small or different sizes are refused naming the sizes") {
  require_weights();
  const io::Image a = pattern(53, 37, 10), b = pattern(53, 37, 11);
  const double v = lpips().distance(a, b);
  CHECK(std::isfinite(v));
  CHECK(v > 0.0);
  const auto maps = lpips().distance_maps(io::to_tensor(a), io::to_tensor(b));
  const size_t want_sizes[5] = {37 * 53, 18 * 26, 9 * 13, 4 * 6, 2 * 3};
  for (int l = 0; l < 5; ++l) CHECK(size_t(maps[l].numel()) == want_sizes[l]);
  const io::Image tiny = pattern(8, 8, 12);
  testing::expect_error([&] { lpips().distance(tiny, tiny); }, "got 8x8");
  const io::Image narrow = pattern(15, 40, 13);
  testing::expect_error([&] { lpips().distance(narrow, narrow); }, "at least 16x16");
  testing::expect_error([&] { lpips().distance(a, pattern(37, 53, 10)); }, "53x37 and 37x53");
}

TEST_CASE("lpips: wrong weight files are refused naming the file") {
  require_weights();
  eval::Lpips l;
  std::string e = testing::error_of([&] { l.load(nn::weights_path(nn::kVggWeightsFile)); });
  CHECK(e.find("not LPIPS weights") != std::string::npos);
  CHECK(e.find(nn::kVggWeightsFile) != std::string::npos);
  e = testing::error_of([&] { l.load("/nonexistent/lpips_vgg16.safetensors"); });
  CHECK(e.find(nn::kFetchWeightsCommand) != std::string::npos);
  if (fs::exists(nn::weights_path("lpips_alex.safetensors"))) {
    e = testing::error_of([&] { l.load(nn::weights_path("lpips_alex.safetensors")); });
    CHECK(e.find("only the VGG-16 variant") != std::string::npos);
  }
}
