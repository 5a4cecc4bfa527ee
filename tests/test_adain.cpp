// 2D AdaIN end to end with the real weights (set-up: `bash scripts/fetch_weights.sh`; without them the
// tests FAIL naming that command): output size and range, alpha = 0 is the plain reconstruction, the
// style statistics really move towards the style, and bad inputs give errors naming the file.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <unistd.h>

#include "host/error.hpp"
#include "lib/io/image.hpp"
#include "lib/nn/weights.hpp"
#include "lib/style/adain.hpp"
#include "tests/testing.hpp"

namespace fs = std::filesystem;
using namespace stylerf;
using host::Tensor;

namespace {

style::AdainModel& model() {
  static style::AdainModel m = [] {
    for (const char* f : {nn::kVggWeightsFile, nn::kDecoderWeightsFile})
      REQUIRE_MESSAGE(fs::exists(nn::weights_path(f)), "pretrained weights missing: " << nn::weights_path(f)
                                                           << " — run `" << std::string(nn::kFetchWeightsCommand) << "` first");
    return style::AdainModel::load_default();
  }();
  return m;
}

// The real photo and painting under ../shared/data, or procedural stand-ins where it is absent.
std::string data_file(const std::string& rel) {
  return testing::image_file_or_procedural(rel, rel.rfind("styles/", 0) == 0 ? "style" : "content");
}

const char* kContent = "scenes/llff/fern/images_8/image000.png";
// Longer side of the images run through the network: 64, or 32 under STYLERF_TEST_SMALL (the simulator).
const int kSize = testing::small_run() ? 32 : 64;
const char* kStyle = "styles/fns_wave.jpg";

// Style distance at relu1_1..relu4_1: mean over layers and channels of (mean_a - mean_b)^2 + (std_a - std_b)^2,
// each layer normalised by the style's own mean square (so the deep layers do not dominate), on the host.
double style_distance(const nn::VggFeatures& a, const nn::VggFeatures& b) {
  double total = 0;
  for (int t = 0; t < 4; ++t) {
    auto stats = [&](const Tensor& f, std::vector<double>& mean, std::vector<double>& sd) {
      auto v = f.to_host();
      int C = int(f.dim(1));
      size_t hw = size_t(f.dim(2) * f.dim(3));
      for (int c = 0; c < C; ++c) {
        double m = 0, q = 0;
        for (size_t i = 0; i < hw; ++i) m += v[c * hw + i];
        m /= hw;
        for (size_t i = 0; i < hw; ++i) q += (v[c * hw + i] - m) * (v[c * hw + i] - m);
        mean.push_back(m);
        sd.push_back(std::sqrt(q / hw));
      }
    };
    std::vector<double> ma, sa, mb, sb;
    stats(a[t], ma, sa);
    stats(b[t], mb, sb);
    double d = 0, norm = 1e-12;
    for (size_t c = 0; c < ma.size(); ++c) {
      d += (ma[c] - mb[c]) * (ma[c] - mb[c]) + (sa[c] - sb[c]) * (sa[c] - sb[c]);
      norm += mb[c] * mb[c] + sb[c] * sb[c];
    }
    total += d / norm;
  }
  return total / 4;
}

}  // namespace

TEST_CASE("adain: a small run gives finite output in [0,1] of the content's size") {
  io::Image out = style::adain_files(model(), data_file(kContent), data_file(kStyle), 1.0f, kSize);
  // fern images_8 is 504x378: longer side 64, other side 48 (multiple of 8); 32 and 24 when small.
  CHECK(out.width == kSize);
  CHECK(out.height == kSize * 3 / 4);
  REQUIRE(testing::all_finite(out.data));
  CHECK(*std::min_element(out.data.begin(), out.data.end()) >= 0.0f);
  CHECK(*std::max_element(out.data.begin(), out.data.end()) <= 1.0f);
  // Not a degenerate image: real structure survives (per-channel spread well above 8-bit noise).
  double m = 0, q = 0;
  for (float v : out.data) m += v;
  m /= out.data.size();
  for (float v : out.data) q += (v - m) * (v - m);
  CHECK(std::sqrt(q / out.data.size()) > 0.05);
}

TEST_CASE("adain wiring: alpha = 0 reproduces the library's own dec(enc(content)); alpha = 1 moves the style statistics") {
  Tensor c = io::to_tensor(style::load_image_for_adain(data_file(kContent), kSize));
  Tensor s = io::to_tensor(style::load_image_for_adain(data_file(kStyle), kSize));
  auto& m = model();
  Tensor recon = m.decoder.forward(m.encoder.forward(c, 4, false)[3]);
  Tensor a0 = style::adain_stylize(m, c, s, 0.0f);
  // t = 0 * adain + 1 * fc is fc exactly (finite values), so the decoder sees the same input: 1e-6.
  testing::check_close(a0.to_host(), testing::to_double(recon.to_host()), 1e-6, 1e-6, "alpha 0 vs dec(enc(c))");

  Tensor a1 = style::adain_stylize(m, c, s, 1.0f);
  Tensor a5 = style::adain_stylize(m, c, s, 0.5f);
  auto fs_ = m.encoder.forward(s, 4, false);
  double d_content = style_distance(m.encoder.forward(c, 4, false), fs_);
  double d_half = style_distance(m.encoder.forward(a5, 4, false), fs_);
  double d_full = style_distance(m.encoder.forward(a1, 4, false), fs_);
  MESSAGE("style distance to the style image: content " << d_content << ", alpha 0.5 " << d_half << ", alpha 1 "
                                                        << d_full);
  CHECK(d_full < 0.5 * d_content);  // stylisation halves the distance at least
  CHECK(d_full < d_half);
  CHECK(d_half < d_content);
}

TEST_CASE("adain: missing or unreadable images and missing weights give errors naming the file") {
  auto error_of = [](auto f) -> std::string {
    try {
      f();
    } catch (const host::Error& e) {
      return e.what();
    }
    return "";
  };
  std::string missing = "/nonexistent/content.png";
  CHECK(error_of([&] { style::adain_files(model(), missing, data_file(kStyle), 1.0f, kSize); }).find(missing) !=
        std::string::npos);
  std::string bad = (fs::temp_directory_path() / ("stylerf_test_adain_" + std::to_string(::getpid()) + ".jpg")).string();
  std::ofstream(bad) << "not a jpeg";
  std::string msg = error_of([&] { style::adain_files(model(), data_file(kContent), bad, 1.0f, kSize); });
  fs::remove(bad);
  CHECK(msg.find(bad) != std::string::npos);

  // An empty weights folder: the error names the expected file and the set-up command.
  std::string empty_dir = (fs::temp_directory_path() / ("stylerf_test_adain_w_" + std::to_string(::getpid()))).string();
  fs::create_directories(empty_dir);
  const char* old = std::getenv("STYLERF_WEIGHTS");
  std::string saved = old ? old : "";
  setenv("STYLERF_WEIGHTS", empty_dir.c_str(), 1);
  msg = error_of([] { style::AdainModel::load_default(); });
  if (old) setenv("STYLERF_WEIGHTS", saved.c_str(), 1); else unsetenv("STYLERF_WEIGHTS");
  fs::remove_all(empty_dir);
  CHECK(msg.find(empty_dir + "/" + nn::kVggWeightsFile) != std::string::npos);
  CHECK(msg.find(nn::kFetchWeightsCommand) != std::string::npos);
}
