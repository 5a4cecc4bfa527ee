// The VGG-19 encoder with the real pretrained weights, and the AdaIN decoder.
//
// The weights come from the set-up command `bash scripts/fetch_weights.sh`; without them these tests FAIL
// (they do not skip) with a message naming that command.
//
//  - encoder forward, all four taps, against a CPU double-precision reference built directly from the
//    weights file (AdaIN layout: conv0 1x1, reflect padding; and torchvision layout: ImageNet
//    normalisation, zero padding);
//  - encoder backward to the input against central differences of that reference;
//  - decoder forward/backward (input and parameter gradients) on a small decoder read from a hand-made
//    file, which also checks how the architecture is derived from the keys;
//  - the real decoder inverts the real encoder far better than a He-initialised one;
//  - the VGG tail (relu3_1 -> relu4_1, the vgg-adain style decoder's front): forward against the reference
//    and against the encoder's own relu4_1, backward against central differences, bad shapes refused.
#include <doctest/doctest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <unistd.h>

#include "host/error.hpp"
#include "lib/io/image.hpp"
#include "lib/io/safetensors.hpp"
#include "lib/nn/decoder.hpp"
#include "lib/nn/vgg.hpp"
#include "lib/nn/vgg_tail.hpp"
#include "lib/nn/weights.hpp"
#include "tests/conv_reference.hpp"
#include "tests/testing.hpp"

namespace fs = std::filesystem;
using namespace stylerf;
using host::Tensor;

namespace {

// ---- CPU double-precision reference ----------------------------------------------------------------

using testing::ref_conv;
using testing::ref_relu;
using testing::ref_pool;
using testing::ref_upsample;
using testing::RefTensor;

// VGG-19 up to relu4_1 from the raw weights, written independently of lib/nn/vgg.cpp's tables.
struct RefVgg {
  struct Conv {
    std::vector<float> w, b;
    int cout;
  };
  Conv input;               // 1x1
  std::vector<Conv> convs;  // conv1_1 .. conv4_1
  bool reflect_pad = true;

  // The four taps for one image x [3,H,W].
  std::vector<RefTensor> forward(const RefTensor& x, int deepest = 4) const {
    std::vector<RefTensor> taps;
    RefTensor h = ref_conv(x, input.w, input.b, 3, 1, false);
    // conv indices after which a tap is taken / a pool follows
    const bool tap_after[9] = {true, false, true, false, true, false, false, false, true};
    const bool pool_after[9] = {false, true, false, true, false, false, false, true, false};
    for (int i = 0; i < 9; ++i) {
      h = ref_conv(h, convs[i].w, convs[i].b, convs[i].cout, 3, reflect_pad);
      ref_relu(h);
      if (tap_after[i]) {
        taps.push_back(h);
        if (int(taps.size()) == deepest) break;
      }
      if (pool_after[i]) h = ref_pool(h);
    }
    return taps;
  }
};

// ---- weights -----------------------------------------------------------------------------------

std::string vgg_path() { return nn::weights_path(nn::kVggWeightsFile); }
std::string decoder_path() { return nn::weights_path(nn::kDecoderWeightsFile); }

// Fails the test (never skips) when the set-up step has not been run.
void require_weights() {
  for (const std::string& p : {vgg_path(), decoder_path()})
    REQUIRE_MESSAGE(fs::exists(p), "pretrained weights missing: " << p << " — run `" << std::string(nn::kFetchWeightsCommand)
                                                                   << "` first (weights folder: $STYLERF_WEIGHTS, "
                                                                      "default ~/.cache/stylerf/weights)");
}

const io::SafeTensors& vgg_file() {
  static io::SafeTensors st = nn::load_weights(vgg_path());
  return st;
}

nn::VggEncoder& encoder() {
  static nn::VggEncoder e = nn::VggEncoder::load_default();
  return e;
}

// AdaIN's vgg_normalised module indices of conv1_1 .. conv4_1 (ReflectionPad2d modules shift them).
const int kAdainIdx[9] = {2, 5, 9, 12, 16, 19, 22, 25, 29};
const int kTorchvisionIdx[9] = {0, 2, 5, 7, 10, 12, 14, 16, 19};
const int kCout[9] = {64, 64, 128, 128, 256, 256, 256, 256, 512};

RefVgg adain_reference() {
  const auto& st = vgg_file();
  RefVgg r;
  r.input = {st.get("0.weight").data, st.get("0.bias").data, 3};
  for (int i = 0; i < 9; ++i)
    r.convs.push_back({st.get(std::to_string(kAdainIdx[i]) + ".weight").data,
                       st.get(std::to_string(kAdainIdx[i]) + ".bias").data, kCout[i]});
  return r;
}

RefTensor ref_from(const std::vector<float>& v, int C, int H, int W) {
  return RefTensor{C, H, W, std::vector<double>(v.begin(), v.end())};
}

double max_abs(const std::vector<double>& v) {
  double m = 0;
  for (double x : v) m = testing::max_or_nan(m, std::fabs(x));
  return m;
}

std::string temp_file(const std::string& name) {
  return (fs::temp_directory_path() / ("stylerf_test_vgg_" + std::to_string(::getpid()) + "_" + name)).string();
}

double rel_error(const std::vector<float>& a, const std::vector<float>& b) {
  double num = 0, den = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    num += (double(a[i]) - b[i]) * (double(a[i]) - b[i]);
    den += double(b[i]) * b[i];
  }
  return std::sqrt(num / den);
}

}  // namespace

TEST_CASE("vgg: the pretrained weights are installed (set-up: bash scripts/fetch_weights.sh)") {
  require_weights();
  auto st = nn::load_weights(vgg_path());
  CHECK(st.get("0.weight").shape == std::vector<int64_t>{3, 3, 1, 1});
  CHECK(nn::VggEncoder::load_default().variant() == nn::VggVariant::AdainNormalised);
}

TEST_CASE("vgg: forward of all four taps matches a double-precision reference (AdaIN layout)") {
  require_weights();
  const int H = 16, W = 24;  // relu4_1 at 2x3: reflect padding stays valid at every level
  auto x = testing::random_uniform(3 * H * W, 11, 0.0f, 1.0f);
  nn::VggFeatures f = encoder().forward(Tensor::from_host(x, {1, 3, H, W}), 4, false);
  auto ref = adain_reference().forward(ref_from(x, 3, H, W));
  for (int t = 0; t < 4; ++t) {
    CHECK(f[t].shape() == host::Shape{1, ref[t].C, ref[t].H, ref[t].W});
    // float32 sums of up to 2304 products of values in the hundreds: relative 1e-4 of the layer's
    // largest activation absorbs the rounding; a wrong weight, padding or index is off by far more.
    testing::check_close(f[t].to_host(), ref[t].v, 1e-4, 1e-4 * max_abs(ref[t].v), nn::vgg_tap_name(t));
  }
  // deepest = 2 stops early and leaves the deeper taps undefined.
  nn::VggFeatures f2 = encoder().forward(Tensor::from_host(x, {1, 3, H, W}), 2, false);
  CHECK(f2[1].defined());
  CHECK(!f2[2].defined());
  CHECK(!f2[3].defined());
}

TEST_CASE("vgg: a batch of two images gives each image's own features") {
  require_weights();
  const int H = 16, W = 16;
  auto a = testing::random_uniform(3 * H * W, 21, 0.0f, 1.0f), b = testing::random_uniform(3 * H * W, 22, 0.0f, 1.0f);
  std::vector<float> ab = a;
  ab.insert(ab.end(), b.begin(), b.end());
  auto fab = encoder().forward(Tensor::from_host(ab, {2, 3, H, W}), 2, false)[1].to_host();
  auto fb = encoder().forward(Tensor::from_host(b, {1, 3, H, W}), 2, false)[1].to_host();
  std::vector<float> second(fab.begin() + fab.size() / 2, fab.end());
  testing::check_close(second, testing::to_double(fb), 1e-5, 1e-4, "image 2 of the batch");
}

TEST_CASE("vgg: torchvision key layout uses ImageNet normalisation and zero padding") {
  require_weights();
  // Re-key the AdaIN convs the torchvision way ("features.<i>"): the loader must pick the torchvision
  // variant, normalise with ImageNet statistics and pad with zeros.
  const auto& st = vgg_file();
  std::map<std::string, io::HostTensor> tv;
  for (int i = 0; i < 9; ++i) {
    tv["features." + std::to_string(kTorchvisionIdx[i]) + ".weight"] = st.get(std::to_string(kAdainIdx[i]) + ".weight");
    tv["features." + std::to_string(kTorchvisionIdx[i]) + ".bias"] = st.get(std::to_string(kAdainIdx[i]) + ".bias");
  }
  std::string path = temp_file("torchvision.safetensors");
  io::save_safetensors(path, tv);
  nn::VggEncoder enc;
  enc.load(path);
  fs::remove(path);
  CHECK(enc.variant() == nn::VggVariant::Torchvision);

  RefVgg r = adain_reference();
  r.reflect_pad = false;
  const double mean[3] = {0.485, 0.456, 0.406}, stdv[3] = {0.229, 0.224, 0.225};
  r.input.w.assign(9, 0.0f);
  for (int c = 0; c < 3; ++c) {
    r.input.w[c * 4] = float(1.0 / stdv[c]);
    r.input.b[c] = float(-mean[c] / stdv[c]);
  }
  const int H = 16, W = 16;
  auto x = testing::random_uniform(3 * H * W, 12, 0.0f, 1.0f);
  auto f = enc.forward(Tensor::from_host(x, {1, 3, H, W}), 2, false);
  auto ref = r.forward(ref_from(x, 3, H, W), 2);
  for (int t = 0; t < 2; ++t)
    testing::check_close(f[t].to_host(), ref[t].v, 1e-4, 1e-4 * max_abs(ref[t].v), nn::vgg_tap_name(t));
}

TEST_CASE("vgg: backward to the input matches central differences of the reference") {
  require_weights();
  const int H = 16, W = 16;
  auto x = testing::random_uniform(3 * H * W, 31, 0.0f, 1.0f);
  RefVgg ref = adain_reference();
  auto taps = ref.forward(ref_from(x, 3, H, W));
  // Loss = sum_t <g_t, tap_t> with random g_t, scaled so every tap contributes comparably.
  struct Probe {
    const char* name;
    std::vector<int> taps;
  };
  for (const Probe& p : {Probe{"relu1_1 + relu2_1", {0, 1}}, Probe{"relu2_1 only", {1}},
                         Probe{"all four taps", {0, 1, 2, 3}}}) {
    INFO(p.name);
    nn::VggFeatures grads;
    std::vector<std::vector<double>> g(4);
    for (int t : p.taps) {
      auto gf = testing::random_normal(taps[t].v.size(), 40 + t, float(1.0 / (1.0 + max_abs(taps[t].v))));
      g[t] = testing::to_double(gf);
      grads[t] = Tensor::from_host(gf, {1, taps[t].C, taps[t].H, taps[t].W});
    }
    encoder().forward(Tensor::from_host(x, {1, 3, H, W}), 4, true);
    auto dx = encoder().backward(grads).to_host();
    REQUIRE(dx.size() == x.size());
    auto loss = [&](const std::vector<double>& xd) {
      auto tp = ref.forward(RefTensor{3, H, W, xd});
      double s = 0;
      for (int t : p.taps) s += testing::dot(g[t], tp[t].v);
      return s;
    };
    const std::vector<size_t> idx = {0, 17, 100, 255, 300, 511, 600, 767};
    auto fd = testing::finite_difference_at(loss, testing::to_double(x), idx, 1e-5);
    std::vector<float> got;
    for (size_t i : idx) got.push_back(dx[i]);
    // Central differences in double with h = 1e-5 are exact to ~1e-8 unless a ReLU or pool switches inside
    // the step (random inputs: not at these indices); float32 backward: rtol 2e-3, atol 1e-3 of the largest.
    testing::check_close(got, fd, 2e-3, 1e-3 * max_abs(fd), std::string("d input, ") + p.name);
  }
}

// relu3_1 -> relu4_1 of the reference: conv3_2, conv3_3, conv3_4 (+ ReLU), pool, conv4_1 (+ ReLU).
RefTensor ref_tail(const RefVgg& r, RefTensor h) {
  for (int i = 5; i < 9; ++i) {
    if (i == 8) h = ref_pool(h);
    h = ref_conv(h, r.convs[size_t(i)].w, r.convs[size_t(i)].b, r.convs[size_t(i)].cout, 3, r.reflect_pad);
    ref_relu(h);
  }
  return h;
}

TEST_CASE("vgg tail: relu3_1 -> relu4_1 matches the reference and the encoder's own relu4_1") {
  require_weights();
  const nn::VggTail tail(encoder());
  {
    // Random non-negative relu3_1-like features: against the double reference
    const int H = 4, W = 6;
    auto x = testing::random_uniform(256 * H * W, 51, 0.0f, 2.0f);
    const Tensor y = tail.forward(Tensor::from_host(x, {1, 256, H, W}));
    const RefTensor ref = ref_tail(adain_reference(), ref_from(x, 256, H, W));
    CHECK(y.shape() == host::Shape{1, 512, H / 2, W / 2});
    testing::check_close(y.to_host(), ref.v, 1e-4, 1e-4 * max_abs(ref.v), "relu4_1 from relu3_1");
  }
  {
    // An image's relu3_1 through the tail is the encoder's relu4_1 of it
    const int H = 32, W = 16;
    auto img = testing::random_uniform(3 * H * W, 52, 0.0f, 1.0f);
    const auto f = encoder().forward(Tensor::from_host(img, {1, 3, H, W}), 4, false);
    const auto want = f[3].to_host();
    testing::check_close(tail.forward(f[2]).to_host(), testing::to_double(want), 1e-5, 1e-5 * max_abs(testing::to_double(want)),
                         "tail(relu3_1) vs relu4_1");
  }
  // Shapes it cannot take are refused before any launch: odd sides (one 2x2 pool), other channel counts.
  CHECK_THROWS_WITH_AS(tail.forward(Tensor::zeros({1, 256, 5, 6})), doctest::Contains("even"), host::Error);
  CHECK_THROWS_WITH_AS(tail.forward(Tensor::zeros({1, 128, 4, 4})), doctest::Contains("[N,256,H,W]"), host::Error);
  nn::VggTail::Ctx empty;
  CHECK_THROWS_AS(tail.backward(empty, Tensor::zeros({1, 512, 2, 2})), host::Error);
}

TEST_CASE("vgg tail: backward matches central differences of the reference") {
  require_weights();
  const nn::VggTail tail(encoder());
  const RefVgg ref = adain_reference();
  const int H = 4, W = 4;
  auto x = testing::random_uniform(256 * H * W, 61, 0.0f, 2.0f);
  const RefTensor y = ref_tail(ref, ref_from(x, 256, H, W));
  auto gf = testing::random_normal(y.v.size(), 62, 1.0f);
  const auto g = testing::to_double(gf);
  nn::VggTail::Ctx ctx;
  tail.forward(Tensor::from_host(x, {1, 256, H, W}), &ctx);
  const auto dx = tail.backward(ctx, Tensor::from_host(gf, {1, 512, H / 2, W / 2})).to_host();
  REQUIRE(dx.size() == x.size());
  auto loss = [&](const std::vector<double>& xd) { return testing::dot(g, ref_tail(ref, RefTensor{256, H, W, xd}).v); };
  const std::vector<size_t> idx = {0, 5, 15, 300, 1000, 2047, 3000, 4095};
  const auto fd = testing::finite_difference_at(loss, testing::to_double(x), idx, 1e-4);
  std::vector<float> got;
  for (size_t i : idx) got.push_back(dx[i]);
  // As the encoder's backward test: float32 against double differences, no ReLU or pool switching inside
  // the step at these random points.
  testing::check_close(got, fd, 2e-3, 1e-3 * max_abs(fd), "d relu3_1");
}

TEST_CASE("vgg: bad weights files name the file and the problem") {
  std::string path = temp_file("bad_vgg.safetensors");
  io::save_safetensors(path, {{"0.weight", {{3, 3, 1, 1}, std::vector<float>(9, 0.0f)}},
                              {"0.bias", {{3}, std::vector<float>(3, 0.0f)}},
                              {"2.weight", {{64, 3, 1, 1}, std::vector<float>(192, 0.0f)}},
                              {"2.bias", {{64}, std::vector<float>(64, 0.0f)}}});
  nn::VggEncoder enc;
  try {
    enc.load(path);
    FAIL("expected an error");
  } catch (const host::Error& e) {
    std::string msg = e.what();
    CHECK(msg.find(path) != std::string::npos);
    CHECK(msg.find("'2.weight' has shape [64, 3, 1, 1], expected [64, 3, 3, 3]") != std::string::npos);
  }
  io::save_safetensors(path, {{"foo", {{1}, {1.0f}}}});
  try {
    enc.load(path);
    FAIL("expected an error");
  } catch (const host::Error& e) {
    CHECK(std::string(e.what()).find("not VGG-19 weights") != std::string::npos);
  }
  fs::remove(path);
  std::string missing = temp_file("missing_vgg.safetensors");
  try {
    enc.load(missing);
    FAIL("expected an error");
  } catch (const host::Error& e) {
    CHECK(std::string(e.what()).find(missing) != std::string::npos);
    CHECK(std::string(e.what()).find(nn::kFetchWeightsCommand) != std::string::npos);
  }
}

TEST_CASE("decoder: architecture from the keys, forward and backward against the reference") {
  // A miniature AdaIN-style decoder: conv 6->4 (module 1), relu, upsample, pad, conv 4->4 (module 5),
  // relu, pad, conv 4->3 (module 8). Gap 4 means an upsampling, gap 3 none.
  const int cin = 6;
  std::map<std::string, io::HostTensor> file;
  struct L {
    int idx, cout, cin;
  };
  const L layers[3] = {{1, 4, cin}, {5, 4, 4}, {8, 3, 4}};
  for (const L& l : layers) {
    file[std::to_string(l.idx) + ".weight"] = {{l.cout, l.cin, 3, 3},
                                               testing::random_normal(size_t(l.cout) * l.cin * 9, 50 + l.idx, 0.3f)};
    file[std::to_string(l.idx) + ".bias"] = {{l.cout}, testing::random_normal(l.cout, 60 + l.idx, 0.1f)};
  }
  std::string path = temp_file("mini_decoder.safetensors");
  io::save_safetensors(path, file);
  nn::ConvStack dec = nn::ConvStack::from_file(path);
  fs::remove(path);
  REQUIRE(dec.layers().size() == 3);
  CHECK(dec.layers()[0].upsample);
  CHECK(dec.layers()[0].w.name == "1.weight");
  CHECK(dec.layers()[2].b.name == "8.bias");
  CHECK(!dec.layers()[1].upsample);
  CHECK(!dec.layers()[2].relu);
  CHECK(dec.in_channels() == cin);
  CHECK(dec.upsamplings() == 1);

  const int h = 3, w = 4;
  auto x = testing::random_normal(size_t(cin) * h * w, 70);
  auto ref_forward = [&](const std::vector<double>& xd, const std::map<std::string, io::HostTensor>& params) {
    RefTensor t{cin, h, w, xd};
    for (int i = 0; i < 3; ++i) {
      const auto& wt = params.at(std::to_string(layers[i].idx) + ".weight").data;
      const auto& bt = params.at(std::to_string(layers[i].idx) + ".bias").data;
      t = ref_conv(t, wt, bt, layers[i].cout, 3, true);
      if (i < 2) ref_relu(t);
      if (i == 0) t = ref_upsample(t);
    }
    return t;
  };
  nn::ConvStack::Ctx ctx;
  Tensor y = dec.forward(Tensor::from_host(x, {1, cin, h, w}), &ctx);
  RefTensor yr = ref_forward(testing::to_double(x), file);
  CHECK(y.shape() == host::Shape{1, 3, 2 * h, 2 * w});
  testing::check_close(y.to_host(), yr.v, 1e-5, 1e-5, "decoder forward");

  auto g = testing::random_normal(yr.v.size(), 71);
  Tensor dx = dec.backward(ctx, Tensor::from_host(g, y.shape()));
  auto gd = testing::to_double(g);
  // d input
  auto fd_x = testing::finite_difference(
      [&](const std::vector<double>& xd) { return testing::dot(gd, ref_forward(xd, file).v); }, testing::to_double(x),
      1e-5);
  testing::check_close(dx.to_host(), fd_x, 1e-3, 1e-4, "decoder d input");
  // d weight / d bias of every layer, probed at a few entries
  for (int i = 0; i < 3; ++i) {
    for (const char* kind : {"weight", "bias"}) {
      std::string key = std::to_string(layers[i].idx) + "." + kind;
      const Tensor& grad = std::string(kind) == "weight" ? dec.layers()[i].w.grad : dec.layers()[i].b.grad;
      REQUIRE(grad.defined());
      auto pd = testing::to_double(file.at(key).data);
      std::vector<size_t> idx = {0, pd.size() / 2, pd.size() - 1};
      auto fd = testing::finite_difference_at(
          [&](const std::vector<double>& p) {
            auto params = file;
            params[key].data.assign(p.begin(), p.end());  // float params: h must survive the rounding
            return testing::dot(gd, ref_forward(testing::to_double(x), params).v);
          },
          pd, idx, 1e-3);
      auto all = grad.to_host();
      std::vector<float> got;
      for (size_t k : idx) got.push_back(all[k]);
      // The perturbed parameters are stored as float (rounding ~3e-8 on values ~0.3, i.e. ~1e-5 relative
      // error of the difference quotient at h = 1e-3). The loss is piecewise linear in one parameter, so
      // the quotient is exact unless a ReLU flips inside +-h; h = 1e-2 does flip some here, 1e-3 does not.
      testing::check_close(got, fd, 1e-3, 1e-3, "decoder d" + key);
    }
  }
}

TEST_CASE("decoder: the pretrained decoder inverts the encoder (vs a He-initialised decoder)") {
  require_weights();
  const std::string lego = testing::image_file_or_procedural("scenes/blender/lego/train/r_0.png", "content");
  const std::array<float, 3> white{1.0f, 1.0f, 1.0f};
  // 128 x 128 (relu4_1 16 x 16); 32 x 32 under STYLERF_TEST_SMALL (the simulator), where the three round trips
  // keep their order and margins (measured 0.61, 9.1, 0.97 against 0.40, 8.4, 0.87 at 128; 16 x 16 does not).
  const int S = testing::small_run() ? 32 : 128;
  io::Image img = io::resize(io::load_image(lego, &white), S, S);
  Tensor x = io::to_tensor(img);

  auto t0 = std::chrono::steady_clock::now();  // the time is printed, never checked
  Tensor f = encoder().forward(x, 4, false)[3];
  auto fh = f.to_host();
  nn::ConvStack dec = nn::load_adain_decoder();
  REQUIRE(dec.in_channels() == 512);
  REQUIRE(dec.upsamplings() == 3);
  auto roundtrip = [&](const nn::ConvStack& d) {
    Tensor y = d.forward(f);
    CHECK(y.shape() == x.shape());
    return rel_error(encoder().forward(y, 4, false)[3].to_host(), fh);
  };
  double real = roundtrip(dec);
  dec.init_he(1234);
  double random = roundtrip(dec);
  // A second, harder baseline: the flat image of x's mean colour (what a decoder that learned nothing
  // but the average would output).
  io::Image flat = img;
  for (int c = 0; c < 3; ++c) {
    double m = 0;
    for (int i = 0; i < S * S; ++i) m += flat.data[size_t(c) * S * S + i];
    std::fill_n(flat.data.begin() + size_t(c) * S * S, S * S, float(m / (S * S)));
  }
  double mean_colour = rel_error(encoder().forward(io::to_tensor(flat), 4, false)[3].to_host(), fh);
  double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::cout << "relu4_1 round trip ||enc(dec(enc(x))) - enc(x)|| / ||enc(x)|| on lego r_0 at " << S << "x" << S
            << ": pretrained " << real << ", He-initialised " << random << ", mean-colour image " << mean_colour
            << " (" << secs << " s)\n";
  CHECK(std::isfinite(real));
  CHECK(real <= random / 3.0);
  CHECK(real < mean_colour);
}
