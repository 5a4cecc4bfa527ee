// File formats: safetensors (round trip, half floats, every kind of corruption names the file), images
// (PNG round trip, alpha compositing, resize, bad files), EXR round trip.
#include <doctest/doctest.h>
#include <stb/stb_image_write.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <unistd.h>

#include "host/error.hpp"
#include "host/files.hpp"
#include "lib/io/exr.hpp"
#include "lib/io/image.hpp"
#include "lib/io/safetensors.hpp"
#include "lib/nn/weights.hpp"
#include "tests/testing.hpp"

namespace fs = std::filesystem;
using namespace stylerf;
using testing::error_of;
using stylerf::host::Error;

namespace {

// A fresh folder per process, removed at exit.
struct TempDir {
  fs::path path;
  TempDir() {
    path = fs::temp_directory_path() / ("stylerf_test_io_" + std::to_string(::getpid()));
    fs::create_directories(path);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
  std::string file(const std::string& name) const { return (path / name).string(); }
};
const TempDir& tmp() {
  static TempDir d;
  return d;
}

void write_bytes(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << bytes;
}

// A safetensors file with the given JSON header text and data bytes (for hand-made corrupt files).
std::string safetensors_bytes(const std::string& header, const std::string& data, uint64_t header_len) {
  std::string out(8, '\0');
  for (int i = 0; i < 8; ++i) out[i] = char((header_len >> (8 * i)) & 0xff);
  return out + header + data;
}
std::string safetensors_bytes(const std::string& header, const std::string& data) {
  return safetensors_bytes(header, data, header.size());
}


bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

}  // namespace

TEST_CASE("safetensors: round trip keeps names, shapes, values and metadata") {
  std::map<std::string, io::HostTensor> in;
  in["conv.weight"] = {{4, 3, 3, 3}, testing::random_normal(108, 1)};
  in["conv.bias"] = {{4}, testing::random_normal(4, 2)};
  in["scalar"] = {{}, {3.5f}};
  in["empty"] = {{0, 5}, {}};
  std::string path = tmp().file("round.safetensors");
  io::save_safetensors(path, in, {{"source", "test"}});
  auto st = io::SafeTensors::load(path);
  CHECK(st.names().size() == 4);
  for (const auto& [name, t] : in) {
    CHECK(st.get(name).shape == t.shape);
    CHECK(st.get(name).data == t.data);  // exact: F32 is stored bit for bit
  }
  CHECK(st.metadata().at("source") == "test");
  // The header is padded so the data starts 8-byte aligned (as the format recommends).
  std::string bytes = host::read_file(path);
  uint64_t hl = 0;
  std::memcpy(&hl, bytes.data(), 8);
  CHECK(hl % 8 == 0);
}

TEST_CASE("safetensors: F16, BF16 and F64 are converted to float") {
  // 1.0, -2.0, 65504 (max half), 2^-24 (smallest subnormal half) in F16; 1.5 and -0.25 in BF16.
  const uint16_t f16[4] = {0x3c00, 0xc000, 0x7bff, 0x0001};
  const uint16_t bf16[2] = {0x3fc0, 0xbe80};
  const double f64[1] = {0.1};
  std::string data(reinterpret_cast<const char*>(f16), 8);
  data += std::string(reinterpret_cast<const char*>(bf16), 4);
  data += std::string(reinterpret_cast<const char*>(f64), 8);
  std::string header =
      R"({"a":{"dtype":"F16","shape":[2,2],"data_offsets":[0,8]},"b":{"dtype":"BF16","shape":[2],"data_offsets":[8,12]},)"
      R"("c":{"dtype":"F64","shape":[1],"data_offsets":[12,20]}})";
  std::string path = tmp().file("half.safetensors");
  write_bytes(path, safetensors_bytes(header, data));
  auto st = io::SafeTensors::load(path);
  auto a = st.get("a", {2, 2}).data;
  CHECK(a[0] == 1.0f);
  CHECK(a[1] == -2.0f);
  CHECK(a[2] == 65504.0f);
  CHECK(a[3] == std::ldexp(1.0f, -24));
  CHECK(st.get("b").data == std::vector<float>{1.5f, -0.25f});
  CHECK(st.get("c").data[0] == 0.1f);
}

TEST_CASE("safetensors: a missing file names the file and the set-up command") {
  std::string path = tmp().file("no_such_weights.safetensors");
  std::string msg = error_of([&] { nn::load_weights(path); });
  CHECK(contains(msg, path));
  CHECK(contains(msg, nn::kFetchWeightsCommand));
}

TEST_CASE("safetensors: corrupt files name the file and what is wrong") {
  const std::string good_entry = R"({"t":{"dtype":"F32","shape":[2],"data_offsets":[0,8]}})";
  const std::string eight(8, '\0');
  struct Case {
    const char* name;
    std::string bytes;
    const char* expect;
  };
  std::vector<Case> cases = {
      {"short", "abc", "too short"},
      {"hugelen", safetensors_bytes(good_entry, eight, 1ull << 40), "header length"},
      {"json", safetensors_bytes("{\"t\": [1, 2", eight), "not valid JSON"},
      {"notobj", safetensors_bytes("[1,2]", eight), "not a JSON object"},
      {"range", safetensors_bytes(R"({"t":{"dtype":"F32","shape":[2],"data_offsets":[0,16]}})", eight),
       "out of range"},
      {"span", safetensors_bytes(R"({"t":{"dtype":"F32","shape":[3],"data_offsets":[0,8]}})", eight), "needs 12"},
      {"dtype", safetensors_bytes(R"({"t":{"dtype":"I64","shape":[1],"data_offsets":[0,8]}})", eight),
       "unsupported dtype"},
      {"fields", safetensors_bytes(R"({"t":{"dtype":"F32","shape":[2]}})", eight), "data_offsets"},
      {"negshape", safetensors_bytes(R"({"t":{"dtype":"F32","shape":[-2],"data_offsets":[0,8]}})", eight),
       "negative"},
  };
  for (const Case& c : cases) {
    std::string path = tmp().file(std::string("corrupt_") + c.name + ".safetensors");
    write_bytes(path, c.bytes);
    std::string msg = error_of([&] { io::SafeTensors::load(path); });
    INFO("case " << c.name << ": " << msg);
    CHECK(contains(msg, path));
    CHECK(contains(msg, c.expect));
  }
  // And the well-formed version of the same file loads.
  std::string path = tmp().file("good.safetensors");
  write_bytes(path, safetensors_bytes(good_entry, eight));
  CHECK(io::SafeTensors::load(path).get("t").data == std::vector<float>{0.0f, 0.0f});
}

TEST_CASE("safetensors: a wrong shape or missing tensor names the file and the tensor") {
  std::string path = tmp().file("shape.safetensors");
  io::save_safetensors(path, {{"w", {{2, 3}, std::vector<float>(6, 1.0f)}}});
  auto st = io::SafeTensors::load(path);
  std::string msg = error_of([&] { st.get("w", {3, 2}); });
  CHECK(contains(msg, path));
  CHECK(contains(msg, "'w' has shape [2, 3], expected [3, 2]"));
  msg = error_of([&] { st.get("missing"); });
  CHECK(contains(msg, path));
  CHECK(contains(msg, "missing"));
}

TEST_CASE("image: PNG round trip is exact to 8 bits") {
  io::Image img;
  img.width = 13;
  img.height = 7;
  img.data = testing::random_uniform(3 * 13 * 7, 3, 0.0f, 1.0f);
  for (float& v : img.data) v = std::round(v * 255.0f) / 255.0f;
  img.data[0] = 1.7f;  // out of range: clamped on save
  img.data[1] = -0.3f;
  std::string path = tmp().file("round.png");
  io::save_png(path, img);
  io::Image back = io::load_image(path);
  REQUIRE(back.width == 13);
  REQUIRE(back.height == 7);
  CHECK(back.data[0] == 1.0f);
  CHECK(back.data[1] == 0.0f);
  for (size_t i = 2; i < img.data.size(); ++i) CHECK(std::fabs(back.data[i] - img.data[i]) < 1e-6f);
  // Planar layout: channel c of pixel (y, x) is data[(c * H + y) * W + x]
  CHECK(back.at(2, 6, 12) == doctest::Approx(img.data.back()).epsilon(1e-6));
}

TEST_CASE("image: RGBA is composited on the background or the alpha dropped") {
  // One pixel: colour (1, 0, 0) at alpha 0.5 (128/255).
  const unsigned char rgba[4] = {255, 0, 0, 128};
  std::string path = tmp().file("alpha.png");
  REQUIRE(stbi_write_png(path.c_str(), 1, 1, 4, rgba, 4));
  const std::array<float, 3> bg{0.0f, 0.0f, 1.0f};
  io::Image over = io::load_image(path, &bg);
  const float a = 128.0f / 255.0f;
  CHECK(over.data[0] == doctest::Approx(a));
  CHECK(over.data[1] == doctest::Approx(0.0f));
  CHECK(over.data[2] == doctest::Approx(1.0f - a));
  io::Image dropped = io::load_image(path);
  CHECK(dropped.data == std::vector<float>{1.0f, 0.0f, 0.0f});
}

TEST_CASE("image: missing, empty and non-image files give errors naming the file") {
  std::string missing = tmp().file("missing.png");
  std::string msg = error_of([&] { io::load_image(missing); });
  CHECK(contains(msg, missing));
  CHECK(contains(msg, "does not exist"));

  std::string empty = tmp().file("empty.png");
  write_bytes(empty, "");
  msg = error_of([&] { io::load_image(empty); });
  CHECK(contains(msg, empty));
  CHECK(contains(msg, "empty"));

  std::string text = tmp().file("text.jpg");
  write_bytes(text, "this is not an image at all, just some text");
  msg = error_of([&] { io::load_image(text); });
  CHECK(contains(msg, text));
  CHECK(contains(msg, "cannot read image"));
}

TEST_CASE("image: resize averages when shrinking and interpolates when enlarging") {
  // Checkerboard 8x8 -> 2x2: each output covers 4x4 source pixels, half white: exactly 0.5.
  io::Image chk;
  chk.width = chk.height = 8;
  chk.data.resize(3 * 64);
  for (int c = 0; c < 3; ++c)
    for (int y = 0; y < 8; ++y)
      for (int x = 0; x < 8; ++x) chk.at(c, y, x) = float((x + y) % 2);
  io::Image small = io::resize(chk, 2, 2);
  for (float v : small.data) CHECK(v == doctest::Approx(0.5f).epsilon(1e-5));
  // Non-integer shrink 10x7 -> 3x2: area averaging keeps the image mean (every source pixel counted once,
  // with total weight 1/(3*2) of the output) to float rounding.
  io::Image rnd;
  rnd.width = 10;
  rnd.height = 7;
  rnd.data = testing::random_uniform(3 * 70, 9, 0.0f, 1.0f);
  io::Image r32 = io::resize(rnd, 3, 2);
  for (int c = 0; c < 3; ++c) {
    double m_in = 0, m_out = 0;
    for (int i = 0; i < 70; ++i) m_in += rnd.data[c * 70 + i] / 70.0;
    for (int i = 0; i < 6; ++i) m_out += r32.data[c * 6 + i] / 6.0;
    CHECK(m_out == doctest::Approx(m_in).epsilon(1e-5));
  }
  // A horizontal ramp 0..3 upsampled to 8 wide: pixel centres map back linearly in the interior.
  io::Image ramp;
  ramp.width = 4;
  ramp.height = 1;
  ramp.data.resize(12);
  for (int c = 0; c < 3; ++c)
    for (int x = 0; x < 4; ++x) ramp.at(c, 0, x) = float(x);
  io::Image big = io::resize(ramp, 8, 1);
  for (int x = 1; x < 7; ++x) CHECK(big.at(0, 0, x) == doctest::Approx((x + 0.5) / 2.0 - 0.5));
  CHECK(big.at(0, 0, 0) == doctest::Approx(0.0f));  // edge clamps
  // fit_size: longer side 512, multiples of 8.
  CHECK(io::fit_size(800, 600, 512, 8) == std::array<int, 2>{512, 384});
  CHECK(io::fit_size(1008, 756, 512, 8) == std::array<int, 2>{512, 384});
  CHECK(io::fit_size(100, 1000, 64, 8) == std::array<int, 2>{8, 64});
}

TEST_CASE("image: tensor conversion keeps the planar layout") {
  io::Image img;
  img.width = 5;
  img.height = 3;
  img.data = testing::random_uniform(45, 4, 0.0f, 1.0f);
  host::Tensor t = io::to_tensor(img);
  CHECK(t.shape() == host::Shape{1, 3, 3, 5});
  CHECK(io::from_tensor(t).data == img.data);
}

TEST_CASE("exr: one- and three-channel float round trip") {
  for (int channels : {1, 3}) {
    std::vector<float> data = testing::random_normal(size_t(channels) * 6 * 4, 5 + channels, 100.0f);
    data[0] = 1e-30f;
    data[1] = 3e30f;
    std::string path = tmp().file("img" + std::to_string(channels) + ".exr");
    io::write_exr(path, data, 6, 4, channels);
    io::ExrImage back = io::read_exr(path);
    CHECK(back.width == 6);
    CHECK(back.height == 4);
    CHECK(back.channels == channels);
    CHECK(back.data == data);  // FLOAT channels are lossless
  }
  CHECK(contains(error_of([&] { io::write_exr(tmp().file("bad.exr"), {1.0f}, 2, 2, 1); }), "bad.exr"));
  CHECK(contains(error_of([&] { io::read_exr(tmp().file("nope.exr")); }), "nope.exr"));
}
