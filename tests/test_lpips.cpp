// LPIPS (v0.1 heads; VGG-16 and AlexNet trunks): the distance-map kernel against a double-precision
// reference (zero features, huge and tiny magnitudes, odd channel counts, 1x1 maps) and its backward against
// central differences; the whole metric, for both trunks, against a double CPU reference built from the
// weights file, against the official lpips 0.1.4 values of tests/data/lpips_official.json (small pairs: the
// distance, each tap, and the masked distance under tests/data/lpips_mask.png) and of
// ../shared/reference/lpips (256x256 pairs); properties (identity, symmetry, the mask, odd sizes, refused
// sizes).
//
// The weights come from the set-up command `bash scripts/fetch_weights.sh`; without them these tests FAIL
// (they do not skip) with a message naming that command.
#include <doctest/doctest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iomanip>
#include <nlohmann/json.hpp>
#include <string>
#include <unistd.h>
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
using testing::ref_pool;
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

using eval::LpipsNet;

std::string lpips_path(LpipsNet net = LpipsNet::Vgg) { return nn::weights_path(eval::lpips_weights_file(net)); }

// Fails the test (never skips) when the set-up step has not been run.
void require_weights(LpipsNet net = LpipsNet::Vgg) {
  REQUIRE_MESSAGE(fs::exists(lpips_path(net)), "LPIPS weights missing: " << lpips_path(net) << " — run `"
                                                                         << std::string(nn::kFetchWeightsCommand)
                                                                         << "` first (weights folder: "
                                                                            "$STYLERF_WEIGHTS, default "
                                                                            "~/.cache/stylerf/weights)");
}

// Loaded once per trunk, on first use (the VGG tests do not need the AlexNet file).
const eval::Lpips& lpips(LpipsNet net = LpipsNet::Vgg) {
  if (net == LpipsNet::Vgg) {
    static eval::Lpips vgg = eval::Lpips::load_default();
    return vgg;
  }
  static eval::Lpips alex = eval::Lpips::load_default(LpipsNet::Alex);
  return alex;
}

// ---- a double CPU reference of the whole metric, independent of lib/eval/lpips.cpp ---------------------

// The trunks' input (lpips' scaling layer, both nets): [0, 1] RGB -> (2 v - 1 - shift) / scale.
RefTensor ref_scaled_input(const io::Image& im) {
  const double shift[3] = {-0.030, -0.088, -0.188}, scale[3] = {0.458, 0.448, 0.450};
  RefTensor h{3, im.height, im.width, std::vector<double>(im.data.size())};
  for (int c = 0; c < 3; ++c)
    for (int y = 0; y < im.height; ++y)
      for (int x = 0; x < im.width; ++x) h.at(c, y, x) = (2.0 * im.at(c, y, x) - 1.0 - shift[c]) / scale[c];
  return h;
}

std::vector<RefTensor> ref_taps(const io::Image& im) {
  const auto st = nn::load_weights(lpips_path());
  RefTensor h = ref_scaled_input(im);
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

// The metric from the two images' taps: the sum over the 5 taps of the spatial mean of the map, with the
// linear heads of `net`'s weights file.
double ref_lpips_of_taps(LpipsNet net, const std::vector<RefTensor>& ta, const std::vector<RefTensor>& tb) {
  const auto st = nn::load_weights(lpips_path(net));
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

double ref_lpips(const io::Image& a, const io::Image& b) {
  return ref_lpips_of_taps(LpipsNet::Vgg, ref_taps(a), ref_taps(b));
}

// AlexNet: a k x k conv with stride and zero padding (torch's Conv2d), a k x k stride-s max pool (floor).
RefTensor ref_conv_strided(const RefTensor& x, const std::vector<float>& w, const std::vector<float>& b, int cout,
                           int k, int stride, int pad) {
  const int ho = (x.H + 2 * pad - k) / stride + 1, wo = (x.W + 2 * pad - k) / stride + 1;
  RefTensor y{cout, ho, wo, std::vector<double>(size_t(cout) * ho * wo)};
  for (int o = 0; o < cout; ++o)
    for (int yy = 0; yy < ho; ++yy)
      for (int xx = 0; xx < wo; ++xx) {
        double s = b[o];
        for (int i = 0; i < x.C; ++i)
          for (int ky = 0; ky < k; ++ky) {
            const int sy = yy * stride + ky - pad;
            if (sy < 0 || sy >= x.H) continue;
            for (int kx = 0; kx < k; ++kx) {
              const int sx = xx * stride + kx - pad;
              if (sx >= 0 && sx < x.W) s += double(w[((size_t(o) * x.C + i) * k + ky) * k + kx]) * x.at(i, sy, sx);
            }
          }
        y.at(o, yy, xx) = s;
      }
  return y;
}

RefTensor ref_pool3(const RefTensor& x) {  // 3x3, stride 2
  RefTensor y{x.C, (x.H - 3) / 2 + 1, (x.W - 3) / 2 + 1, {}};
  y.v.resize(size_t(y.C) * y.H * y.W);
  for (int c = 0; c < x.C; ++c)
    for (int yy = 0; yy < y.H; ++yy)
      for (int xx = 0; xx < y.W; ++xx) {
        double m = x.at(c, 2 * yy, 2 * xx);
        for (int ky = 0; ky < 3; ++ky)
          for (int kx = 0; kx < 3; ++kx) m = std::max(m, x.at(c, 2 * yy + ky, 2 * xx + kx));
        y.at(c, yy, xx) = m;
      }
  return y;
}

std::vector<RefTensor> ref_taps_alex(const io::Image& im) {
  const auto st = nn::load_weights(lpips_path(LpipsNet::Alex));
  RefTensor h = ref_scaled_input(im);
  struct L {
    int cout, k, stride, pad;
  };
  const L layers[5] = {{64, 11, 4, 2}, {192, 5, 1, 2}, {384, 3, 1, 1}, {256, 3, 1, 1}, {256, 3, 1, 1}};
  std::vector<RefTensor> taps;
  for (int i = 0; i < 5; ++i) {
    const std::string key = "trunk." + std::to_string(i);
    h = ref_conv_strided(h, st.get(key + ".weight").data, st.get(key + ".bias").data, layers[i].cout, layers[i].k,
                         layers[i].stride, layers[i].pad);
    testing::ref_relu(h);
    taps.push_back(h);
    if (i < 2) h = ref_pool3(h);
  }
  return taps;
}

double ref_lpips_alex(const io::Image& a, const io::Image& b) {
  return ref_lpips_of_taps(LpipsNet::Alex, ref_taps_alex(a), ref_taps_alex(b));
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

// ---- checks run for both trunks -------------------------------------------------------------------------

// The masked tests' images for a W x H image a: the mask is 1 on the left third (x < W / 3) and 0 elsewhere;
// b is a with uniform [0, 1] noise in the right third (x >= 2 W / 3), inside is a with the same noise in
// the left third.
struct MaskedNoise {
  std::vector<float> mask;
  io::Image b, inside;
};

MaskedNoise masked_noise(const io::Image& a) {
  const int W = a.width, H = a.height;
  MaskedNoise m{std::vector<float>(size_t(W) * H, 0.0f), a, a};
  const auto noise = testing::random_uniform(a.data.size(), 9, 0.0f, 1.0f);
  for (int c = 0; c < 3; ++c)
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        if (c == 0 && x < W / 3) m.mask[size_t(y) * W + x] = 1.0f;
        const size_t i = (size_t(c) * H + y) * W + x;
        if (x >= 2 * W / 3) m.b.data[i] = noise[i];
        if (x < W / 3) m.inside.data[i] = noise[i];
      }
  return m;
}

// `net`'s distances against the official lpips 0.1.4 values (`key` of each pair in pairs.json) in
// ../shared/reference/lpips; reported as skipped when that folder is absent.
void check_official_values(LpipsNet net, const char* key) {
  const std::string dir = testing::shared_reference_dir("lpips");
  if (dir.empty()) {
    testing::report_skipped("../shared/reference/lpips is absent: the 256x256 official lpips values are not "
                            "compared (the small pairs of tests/data are)");
    return;
  }
  const auto j = nlohmann::json::parse(host::read_file(dir + "/pairs.json"));
  REQUIRE(j["pairs"].size() == 6);
  for (const auto& pair : j["pairs"]) {
    const std::string fa = pair["a"], fb = pair["b"];
    const double want = pair[key];
    const double got = lpips(net).distance(io::load_image(dir + "/" + fa), io::load_image(dir + "/" + fb));
    MESSAGE(std::setprecision(7) << fa << " vs " << fb << ": ours " << got << ", official " << want << ", |diff| "
                                 << std::fabs(got - want));
    // pairs.json holds 6 decimals (rounding 5e-7); float32 against the official float32 is ~1e-6.
    CHECK(std::fabs(got - want) <= 1e-5);
  }
}

// ---- the official values of tests/data/lpips_official.json (tests/data/make_lpips_official.py) --------------

// The official distance, its five taps' spatial means and (where the pair has them) the masked distance
// and its taps, all in float64, against ours (float32). Both are sums of ~10^4 products of magnitude <= 1:
// float32 accumulation keeps ~1e-6.
constexpr double kOfficialTol = 1e-5;

std::string fixture(const std::string& name) { return std::string(STYLERF_TEST_FIXTURES) + "/" + name; }

const nlohmann::json& official_pairs() {
  static const nlohmann::json j = nlohmann::json::parse(host::read_file(fixture("lpips_official.json")));
  return j;
}

// Plane 0 of tests/data/lpips_mask.png, a grey PNG of weights.
std::vector<float> official_mask() {
  const io::Image m = io::load_image(fixture(official_pairs()["mask"].get<std::string>()));
  return std::vector<float>(m.data.begin(), m.data.begin() + size_t(m.width) * m.height);
}

void check_official_small_pairs(LpipsNet net) {
  const eval::Lpips& l = lpips(net);
  const char* key = eval::lpips_net_name(net);
  const std::vector<float> mask = official_mask();
  int masked_pairs = 0;
  for (const auto& pair : official_pairs()["pairs"]) {
    const std::string name = pair["name"];
    CAPTURE(name);
    const io::Image a = io::load_image(fixture(pair["a"])), b = io::load_image(fixture(pair["b"]));
    const auto& want = pair[key];
    const double got = l.distance(a, b);
    INFO(std::setprecision(9) << "ours " << got << ", official " << want["lpips"].get<double>());
    CHECK(std::fabs(got - want["lpips"].get<double>()) <= kOfficialTol);
    const auto maps = l.distance_maps(io::to_tensor(a), io::to_tensor(b));
    REQUIRE(maps.size() == want["taps"].size());
    for (size_t t = 0; t < maps.size(); ++t) {
      CAPTURE(t);
      REQUIRE(maps[t].numel() == want["tap_sizes"][t][0].get<int64_t>() * want["tap_sizes"][t][1].get<int64_t>());
      double sum = 0;
      for (float v : maps[t].to_host()) sum += v;
      const double mean = sum / double(maps[t].numel()), want_tap = want["taps"][t];
      INFO("tap mean: ours " << mean << ", official " << want_tap);
      CHECK(std::fabs(mean - want_tap) <= kOfficialTol);
    }
    if (pair["a"] == pair["b"]) CHECK(got == 0.0);
    if (!want.contains("masked")) continue;
    ++masked_pairs;
    const double got_masked = l.distance(a, b, mask), want_masked = want["masked"];
    INFO("masked: ours " << got_masked << ", official maps under the mask " << want_masked);
    CHECK(std::fabs(got_masked - want_masked) <= kOfficialTol);
    // The mask changes the value, so the comparison says something about the mask's pooling.
    if (want_masked > 0) CHECK(std::fabs(want_masked - want["lpips"].get<double>()) > 100 * kOfficialTol);
  }
  CHECK(masked_pairs >= 3);
}

// The pair's size: 64x48, or 40x32 under STYLERF_TEST_SMALL (the simulator; AlexNet needs 31x31).
const int kPairW = testing::small_run() ? 40 : 64, kPairH = testing::small_run() ? 32 : 48;

// For two kPairW x kPairH patterns a, b: d(a, a) == 0, d(a, b) == d(b, a) > 0, and
// 0 < d(a, slightly noisy a) < d(a, b). Returns d(a, b).
double check_identity_symmetry(const eval::Lpips& l) {
  const io::Image a = pattern(kPairW, kPairH, 3), b = pattern(kPairW, kPairH, 4);
  CHECK(l.distance(a, a) == 0.0);
  const double ab = l.distance(a, b), ba = l.distance(b, a);
  CHECK(ab > 0.0);
  CHECK(ab == doctest::Approx(ba).epsilon(1e-6));
  io::Image slightly = a;
  const auto noise = testing::random_uniform(a.data.size(), 5, -0.02f, 0.02f);
  for (size_t i = 0; i < a.data.size(); ++i) slightly.data[i] = std::min(1.0f, std::max(0.0f, a.data[i] + noise[i]));
  const double small = l.distance(a, slightly);
  CHECK(small > 0.0);
  CHECK(small < ab);
  return ab;
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

TEST_CASE("lpips: the official values of tests/data (lpips 0.1.4, VGG): distance, each tap, masked") {
  require_weights();
  check_official_small_pairs(LpipsNet::Vgg);
}

TEST_CASE("lpips: the official values of ../shared/reference/lpips (lpips 0.1.4, VGG)" * doctest::test_suite("shared")) {
  require_weights();
  check_official_values(LpipsNet::Vgg, "lpips_vgg");
}

TEST_CASE("lpips: identity, symmetry, and a larger difference for a larger change") {
  require_weights();
  check_identity_symmetry(lpips());
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
    const auto [mask, b, inside] = masked_noise(a);
    const double unmasked = lpips().distance(a, b), masked = lpips().distance(a, b, mask);
    INFO("unmasked " << unmasked << ", masked " << masked);
    CHECK(unmasked > 0.05);
    // Only the deep taps (receptive fields of 100-196 px) see the noise from inside the mask: masked is
    // about 1/75 of unmasked here.
    CHECK(masked < 0.05 * unmasked);
    // The same noise inside the mask counts fully.
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
  // Each file loads as its own trunk, whatever load() is given.
  l.load(lpips_path(LpipsNet::Vgg));
  CHECK(l.net() == LpipsNet::Vgg);
  if (fs::exists(lpips_path(LpipsNet::Alex))) {
    l.load(lpips_path(LpipsNet::Alex));
    CHECK(l.net() == LpipsNet::Alex);
    CHECK(l.min_side() == eval::kLpipsAlexMinSide);
  }
  // A VGG file under the AlexNet name is refused by load_default(Alex), naming both trunks.
  const fs::path dir = fs::temp_directory_path() / ("stylerf_lpips_weights_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  fs::copy_file(lpips_path(LpipsNet::Vgg), dir / eval::kLpipsAlexWeightsFile, fs::copy_options::overwrite_existing);
  const char* old = std::getenv("STYLERF_WEIGHTS");
  const std::string saved = old ? old : "";
  setenv("STYLERF_WEIGHTS", dir.c_str(), 1);
  e = testing::error_of([] { eval::Lpips::load_default(LpipsNet::Alex); });
  if (old) setenv("STYLERF_WEIGHTS", saved.c_str(), 1);
  else unsetenv("STYLERF_WEIGHTS");
  fs::remove_all(dir);
  CHECK(e.find("holds the VGG-16 LPIPS weights, expected AlexNet") != std::string::npos);
  CHECK(eval::parse_lpips_net("alex") == LpipsNet::Alex);
  testing::expect_error([] { eval::parse_lpips_net("squeeze"); }, "unknown net 'squeeze'");
}

// ---- AlexNet ------------------------------------------------------------------------------------------

TEST_CASE("lpips alex: the weights are installed (set-up: bash scripts/fetch_weights.sh)") {
  require_weights(LpipsNet::Alex);
  const auto st = nn::load_weights(lpips_path(LpipsNet::Alex));
  CHECK(st.get("trunk.0.weight").shape == std::vector<int64_t>{64, 3, 11, 11});
  CHECK(st.get("trunk.1.weight").shape == std::vector<int64_t>{192, 64, 5, 5});
  CHECK(st.get("trunk.4.weight").shape == std::vector<int64_t>{256, 256, 3, 3});
  CHECK(st.get("lin.2.weight").shape == std::vector<int64_t>{384});
  CHECK(lpips(LpipsNet::Alex).loaded());
  CHECK(lpips(LpipsNet::Alex).net() == LpipsNet::Alex);
}

TEST_CASE("lpips alex: tap sizes floor like torch (256 -> 63, 31, 15; the minimum 31 -> 7, 3, 1)") {
  using S = std::array<int, 2>;
  CHECK(eval::Lpips::tap_sizes(LpipsNet::Alex, 256, 256) ==
        std::vector<S>{{63, 63}, {31, 31}, {15, 15}, {15, 15}, {15, 15}});
  CHECK(eval::Lpips::tap_sizes(LpipsNet::Alex, 37, 53) == std::vector<S>{{8, 12}, {3, 5}, {1, 2}, {1, 2}, {1, 2}});
  CHECK(eval::Lpips::tap_sizes(LpipsNet::Alex, 31, 31) == std::vector<S>{{7, 7}, {3, 3}, {1, 1}, {1, 1}, {1, 1}});
  // One below the minimum: 30 -> 6 -> 2 -> no position.
  CHECK(eval::Lpips::tap_sizes(LpipsNet::Alex, 30, 31)[2] == S{0, 1});
  // The VGG overload is unchanged.
  CHECK(eval::Lpips::tap_sizes(37, 53) == eval::Lpips::tap_sizes(LpipsNet::Vgg, 37, 53));
}

TEST_CASE("lpips alex: matches a double-precision CPU reference (odd sizes floor at every stride)") {
  require_weights(LpipsNet::Alex);
  for (auto wh : {std::array<int, 2>{53, 37}, std::array<int, 2>{31, 31}, std::array<int, 2>{70, 45}}) {
    CAPTURE(wh[0]);
    CAPTURE(wh[1]);
    const io::Image a = pattern(wh[0], wh[1], 21), b = pattern(wh[0], wh[1], 22);
    const double got = lpips(LpipsNet::Alex).distance(a, b), want = ref_lpips_alex(a, b);
    INFO("ours " << got << ", reference " << want);
    CHECK(std::fabs(got - want) <= 1e-5 + 1e-4 * want);
  }
}

TEST_CASE("lpips alex: the official values of tests/data (lpips 0.1.4, AlexNet): distance, each tap, masked") {
  require_weights(LpipsNet::Alex);
  check_official_small_pairs(LpipsNet::Alex);
}

TEST_CASE("lpips alex: the official values of ../shared/reference/lpips (lpips 0.1.4, AlexNet)" *
          doctest::test_suite("shared")) {
  require_weights(LpipsNet::Alex);
  check_official_values(LpipsNet::Alex, "lpips_alex");
}

TEST_CASE("lpips alex: identity, symmetry, and a larger difference for a larger change") {
  require_weights(LpipsNet::Alex);
  const double ab = check_identity_symmetry(lpips(LpipsNet::Alex));
  // A different metric from VGG's on the same pair.
  CHECK(std::fabs(ab - lpips().distance(pattern(kPairW, kPairH, 3), pattern(kPairW, kPairH, 4))) > 1e-3);
}

TEST_CASE("lpips alex: masked distance") {
  require_weights(LpipsNet::Alex);
  const eval::Lpips& l = lpips(LpipsNet::Alex);
  const int W = 96, H = 48;
  const io::Image a = pattern(W, H, 6), other = pattern(W, H, 7);
  const std::vector<float> ones(size_t(W) * H, 1.0f);
  CHECK(l.distance(a, other, ones) == doctest::Approx(l.distance(a, other)).epsilon(1e-12));

  SUBCASE("the definition: each tap weighted by the mask's area average over its cells") {
    // Independently of the implementation's coverage weights: split every input pixel into h x w
    // sub-pixels (h, w the tap's size); then tap cell (y, x) covers exactly the H x W sub-pixels
    // [y H, (y + 1) H) x [x W, (x + 1) W), and its mask is their plain mean.
    auto mask = testing::random_uniform(size_t(W) * H, 8, 0.0f, 1.0f);
    const auto maps = l.distance_maps(io::to_tensor(a), io::to_tensor(other));
    const auto sizes = eval::Lpips::tap_sizes(LpipsNet::Alex, H, W);
    double want = 0;
    for (int t = 0; t < 5; ++t) {
      const int h = sizes[t][0], w = sizes[t][1];
      const auto dm = maps[t].to_host();
      REQUIRE(dm.size() == size_t(h) * w);
      double num = 0, den = 0;
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
          double m = 0;
          for (int sy = y * H; sy < (y + 1) * H; ++sy)
            for (int sx = x * W; sx < (x + 1) * W; ++sx) m += mask[size_t(sy / h) * W + sx / w];
          m /= double(H) * W;
          num += m * dm[size_t(y) * w + x];
          den += m;
        }
      want += num / den;
    }
    CHECK(l.distance(a, other, mask) == doctest::Approx(want).epsilon(1e-9));
  }
  SUBCASE("differences where the mask is 0 count much less") {
    // Mask: the left third. b = a with noise in the right third; the same noise inside the mask counts fully.
    const auto [mask, b, inside] = masked_noise(a);
    const double unmasked = l.distance(a, b), masked = l.distance(a, b, mask), in = l.distance(a, inside, mask);
    INFO("unmasked " << unmasked << ", masked " << masked << ", noise inside the mask " << in);
    CHECK(unmasked > 0.05);
    // The deep taps are coarse (5 positions across at relu3..5, receptive fields of 99-163 px), so the noise
    // 32 px from the mask's edge reaches the masked cells a little: masked is about 1/26 of unmasked here,
    // and noise inside the mask 50 times masked.
    CHECK(masked < 0.1 * unmasked);
    CHECK(in > 20.0 * masked);
  }
  SUBCASE("an all-zero mask gives 0; bad masks are refused") {
    CHECK(l.distance(a, other, std::vector<float>(size_t(W) * H, 0.0f)) == 0.0);
    testing::expect_error([&] { l.distance(a, other, std::vector<float>(10, 1.0f)); }, "the mask has 10 values");
  }
}

TEST_CASE("lpips alex: odd sizes run, too small or different sizes are refused naming the sizes") {
  require_weights(LpipsNet::Alex);
  const eval::Lpips& l = lpips(LpipsNet::Alex);
  const io::Image a = pattern(53, 37, 10), b = pattern(53, 37, 11);
  const double v = l.distance(a, b);
  CHECK(std::isfinite(v));
  CHECK(v > 0.0);
  const auto maps = l.distance_maps(io::to_tensor(a), io::to_tensor(b));
  const size_t want_sizes[5] = {8 * 12, 3 * 5, 1 * 2, 1 * 2, 1 * 2};
  for (int t = 0; t < 5; ++t) CHECK(size_t(maps[t].numel()) == want_sizes[t]);
  // The smallest input: every tap of relu3..5 is one position.
  const io::Image s31 = pattern(31, 31, 12), t31 = pattern(31, 31, 13);
  CHECK(std::isfinite(l.distance(s31, t31)));
  CHECK(l.distance(s31, s31) == 0.0);
  // VGG takes 16..30, AlexNet refuses them.
  const io::Image narrow = pattern(40, 30, 14);
  CHECK(std::isfinite(lpips().distance(narrow, narrow)));
  const std::string e = testing::error_of([&] { l.distance(narrow, narrow); });
  CHECK(e.find("at least 31x31 for AlexNet") != std::string::npos);
  CHECK(e.find("got 40x30") != std::string::npos);
  testing::expect_error([&] { l.distance(a, pattern(37, 53, 10)); }, "53x37 and 37x53");
  testing::expect_error([&] { l.distance_maps(Tensor::zeros({1, 3, 30, 64}), Tensor::zeros({1, 3, 30, 64})); },
                        "H and W must be >= 31 (AlexNet)");
}
