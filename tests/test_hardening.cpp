// Hardening tests, each the reproduction of a defect it would have caught:
//  - SHA-256 against the FIPS 180-4 vectors; weights refused when their sum differs from manifest.json or
//    a value is not finite (naming the file and tensor);
//  - atomic writes: the temporary file is removed when SIGTERM arrives mid-write, stale ones of dead
//    writers are removed at the next write, a live writer's are left alone;
//  - images: .jpg outputs are JPEG, unknown types refused, PNG bytes never under a .jpg name; AdaIN sizes
//    checked before any compute (a 2000x2 image, --size 8 or 10^9);
//  - make-scene refuses 3..5 views (no test split) and a supersample of 0;
//  - the command line: out-of-range or NaN numbers name their option, -o is checked before training (a
//    folder, a parent that is a file, an existing checkpoint without --force), --resume --iters below the
//    checkpoint's iteration, a checkpoint path that is a folder, a device type that is absent, another
//    scene's folder for a checkpoint.
#include <doctest/doctest.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <sys/wait.h>
#include <unistd.h>

#include "host/error.hpp"
#include "host/files.hpp"
#include "host/fp_mode.hpp"
#include "host/runtime.hpp"
#include "host/tensor.hpp"
#include "lib/io/image.hpp"
#include "lib/io/safetensors.hpp"
#include "lib/io/sha256.hpp"
#include "lib/nn/ops.hpp"
#include "lib/nn/weights.hpp"
#include "lib/scene/make_scene.hpp"
#include "lib/style/adain.hpp"
#include "tests/cli_runner.hpp"
#include "tests/small_scene.hpp"
#include "tests/testing.hpp"

using namespace stylerf;
namespace fs = std::filesystem;

namespace {
fs::path fresh_dir(const std::string& name) {
  const fs::path d = testing::small_work_dir() / name;
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}
bool has(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }
}  // namespace

TEST_CASE("sha256 matches the FIPS 180-4 test vectors") {
  CHECK(io::sha256_hex("") == "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  CHECK(io::sha256_hex("abc") == "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  CHECK(io::sha256_hex("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq") ==
        "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
  CHECK(io::sha256_hex(std::string(1000000, 'a')) == "cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0");
  // Streaming in odd pieces gives the same sum.
  io::Sha256 h;
  const std::string text(1000, 'x');
  for (size_t i = 0; i < text.size(); i += 37) h.update(text.data() + i, std::min<size_t>(37, text.size() - i));
  CHECK(h.hex() == io::sha256_hex(text));
}

TEST_CASE("weights: the manifest's sha256 and finite values are checked at load") {
  const fs::path d = fresh_dir("weights");
  const std::string file = (d / "w.safetensors").string();
  auto write = [&](std::vector<float> v, const std::string& sum) {
    io::save_safetensors(file, {{"layer.weight", {{int64_t(v.size())}, v}}});
    const std::string s = sum.empty() ? io::sha256_file(file) : sum;
    host::write_file_atomic((d / "manifest.json").string(),
                            nlohmann::json{{"files", {{"w.safetensors", {{"sha256", s}}}}}}.dump());
    fs::remove(d / ".w.safetensors.verified");
  };
  write({1, 2, 3}, "");
  CHECK(nn::load_weights(file).get("layer.weight").data.size() == 3);
  CHECK(fs::exists(d / ".w.safetensors.verified"));
  CHECK(nn::load_weights(file).has("layer.weight"));  // the stamp short-cuts the second check
  write({1, NAN, 3}, "");
  std::string e = testing::error_of([&] { nn::load_weights(file); });
  CHECK(has(e, "w.safetensors"));
  CHECK(has(e, "layer.weight has a non-finite value at element 1"));
  write({1, 2, 3}, std::string(64, '0'));
  e = testing::error_of([&] { nn::load_weights(file); });
  CHECK(has(e, "differs from " + std::string(64, '0')));
  CHECK(has(e, "fetch_weights"));
}

TEST_CASE("atomic writes: no temporary file survives SIGTERM, stale ones are removed") {
  const fs::path d = fresh_dir("atomic");
  const std::string target = (d / "out.ckpt").string();
  const pid_t pid = ::fork();
  REQUIRE(pid >= 0);
  if (pid == 0) {
    ::signal(SIGTERM, SIG_DFL);  // as in a command-line run (the test runner installs its own handlers)
    host::write_atomic_with(target, [&](const std::string& tmp) {
      std::ofstream(tmp) << std::string(1 << 20, 'x');
      ::raise(SIGTERM);  // interrupted mid-write
    });
    ::_exit(0);  // not reached
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  CHECK(WIFSIGNALED(status));
  CHECK(WTERMSIG(status) == SIGTERM);
  int left = 0;
  for (const auto& e : fs::directory_iterator(d)) left += has(e.path().filename().string(), ".tmp-");
  CHECK(left == 0);
  CHECK_FALSE(fs::exists(target));

  // A killed writer's leftover (a PID that no longer runs) goes; a live process's stays.
  const pid_t dead = ::fork();
  if (dead == 0) ::_exit(0);
  ::waitpid(dead, nullptr, 0);
  const std::string stale = target + ".tmp-" + std::to_string(dead);
  const std::string live = target + ".tmp-" + std::to_string(::getpid() == 1 ? 2 : 1);  // init: always alive
  std::ofstream(stale) << "partial";
  std::ofstream(live) << "in progress";
  host::write_file_atomic(target, "done");
  CHECK_FALSE(fs::exists(stale));
  CHECK(fs::exists(live));
  CHECK(host::read_file(target) == "done");
}

TEST_CASE("images: output types by name, AdaIN sizes checked before compute") {
  const fs::path d = fresh_dir("images");
  io::Image img;
  img.width = img.height = 16;
  img.data.assign(3 * 16 * 16, 0.5f);
  io::save_image((d / "a.jpg").string(), img);
  const std::string bytes = host::read_file((d / "a.jpg").string());
  CHECK((unsigned char)bytes[0] == 0xFF);
  CHECK((unsigned char)bytes[1] == 0xD8);  // a JPEG, not PNG bytes
  CHECK(io::load_image((d / "a.jpg").string()).width == 16);
  io::save_image((d / "a.png").string(), img);
  CHECK(host::read_file((d / "a.png").string()).substr(1, 3) == "PNG");
  CHECK(has(testing::error_of([&] { io::save_image((d / "a.gif").string(), img); }), "unknown image type '.gif'"));
  CHECK(has(testing::error_of([&] { io::save_png((d / "b.jpeg").string(), img); }), "PNG data under a JPEG name"));

  io::Image wide;
  wide.width = 2000;
  wide.height = 2;
  wide.data.assign(3 * 2000 * 2, 0.3f);
  io::save_png((d / "wide.png").string(), wide);
  std::string e = testing::error_of([&] { style::load_image_for_adain((d / "wide.png").string(), 512); });
  CHECK(has(e, "wide.png is 2000x2"));
  CHECK(has(e, "needs 16"));
  CHECK(has(testing::error_of([&] { style::load_image_for_adain((d / "a.png").string(), 8); }), "size must be in ["));
  CHECK(has(testing::error_of([&] { style::load_image_for_adain((d / "a.png").string(), 1000000000); }), "size must be in ["));
}

TEST_CASE("make-scene: every split non-empty, options in range") {
  const fs::path d = fresh_dir("make_scene");
  scene::MakeSceneOptions o;
  o.size = 8;
  for (int views : {3, 4, 5}) {
    o.views = views;
    CHECK(has(testing::error_of([&] { scene::make_scene((d / "s").string(), o); }), "views must be in 6.."));
  }
  o.views = 6;
  o.supersample = 0;
  CHECK(has(testing::error_of([&] { scene::make_scene((d / "s").string(), o); }), "supersample must be in 1..16"));
  o.supersample = 1;
  scene::make_scene((d / "s").string(), o);
  const scene::Scene s = scene::load_scene((d / "s").string());
  CHECK(s.test.size() == 1);
  CHECK(s.train.size() == 4);
}

TEST_CASE("command line: options are checked before any work, with messages naming them") {
  const fs::path d = fresh_dir("cli");
  const std::string scene_dir = testing::small_scene().root;
  const std::string out = (d / "density.ckpt").string();
  auto expect = [&](const std::string& args, const std::string& needle) {
    const testing::CliRun r = testing::run_cli(args);
    INFO(args);
    INFO(r.output);
    CHECK(r.code == 1);
    CHECK(has(r.output, needle));
  };
  const std::string td = "train-density --scene '" + scene_dir + "' ";
  expect(td + "--iters 0 -o " + out, "--iters must be an integer in [1,");
  expect(td + "--minutes nan -o " + out, "--minutes must be a number");
  expect(td + "--lr-grid nan -o " + out, "--lr-grid must be a number");
  expect(td + "--lr-grid -1 -o " + out, "--lr-grid must be a number");
  expect(td + "--batch 0 -o " + out, "--batch must be in [1, 4194304], got 0");  // DensityTrainConfig::validate's rule
  expect(td + "--iters 100 --upsample-at 50,20 -o " + out, "--upsample-at must be strictly increasing");
  expect(td + "--ckpt-every -5 -o " + out, "--ckpt-every");
  expect(td + "--eval-views -1 -o " + out, "--eval-views");
  expect(td + "--init-voxels 64^3 --final-voxels 32^3 -o " + out, "must not exceed --final-voxels");
  expect(td + "--final-voxels 100000^3 -o " + out, "beyond the largest grid");
  expect(td + "--ert nan -o " + out, "--ert must be a number");
  expect(td + "--ert 0.9 -o " + out, "--ert must be a number");
  expect(td + "--shading fancy -o " + out, "--shading: unknown 'fancy'");
  expect(td, "-o CKPT is required");
  expect(td + "-o '" + d.string() + "'", "is a folder");
  std::ofstream((d / "a_file").string()) << "x";
  expect(td + "-o '" + (d / "a_file" / "x.ckpt").string() + "'", "is a file, not a folder");
  expect(td + "--resume -o " + out, "does not exist");
  // A short real run, then the refusals that need a checkpoint.
  const std::string small = td + "--iters 12 --batch 256 --init-voxels 16^3 --final-voxels 20^3 --upsample-at 6 "
                                 "--mask-at 8 --log-every 0 --eval-views 1 -o " + out;
  testing::CliRun r = testing::run_cli(small);
  INFO(r.output);
  REQUIRE(r.code == 0);
  expect(small, "exists: pass --resume to continue it or --force");
  expect(td + "--resume --iters 10 -o " + out, "already at iteration 12");
  expect(td + "--resume --lr-grid 0.1 -o " + out, "drop the model and schedule options");
  expect(td + "--resume --shading deferred -o " + out, "drop the model and schedule options");
  // train-features: the config's rules are the library's (FeatureTrainConfig::validate), named by flag.
  const std::string tf = "train-features --density " + out + " -o '" + (d / "f.ckpt").string() + "' ";
  expect(tf + "--tv -5", "--tv must be >= 0");  // once silently ignored
  expect(tf + "--patch 12", "--patch must be a positive multiple of 8, got 12");
  expect(tf + "--lr-grid 0", "--lr-grid must be a positive number");
  expect(tf + "--iters 0", "--iters must be >= 1, got 0");
  expect(tf + "--minutes 1 --iters 5", "--minutes and --iters exclude each other");
  expect("render --ckpt " + out + " --ert -1 -o '" + (d / "r").string() + "'", "--ert must be a number");
  expect("bench render --ckpt " + out + " --ert 0,x", "--ert: 'x' is not a threshold");
  expect("bench render", "--ckpt (a density checkpoint) is required");
  expect("render --ckpt '" + d.string() + "' -o '" + (d / "r").string() + "'", "is a folder, not a checkpoint file");
  // Another scene's folder: another name.
  scene::MakeSceneOptions mo;
  mo.size = 16;
  mo.views = 6;
  scene::make_scene((d / "other").string(), mo);
  expect("render --ckpt " + out + " --scene '" + (d / "other").string() + "' -o '" + (d / "r").string() + "'",
         "was trained on scene");
  expect("make-scene --num-views 4 -o '" + (d / "few").string() + "'", "--num-views must be in 6..");
  expect("make-scene --pixel-samples 0 -o '" + (d / "few").string() + "'", "--pixel-samples must be in 1..16");
  expect("adain --content a.png --style b.png --size 1000000000 -o x.png", "--size must be in [16, 4096]");
  expect("adain --content a.png --style b.png -o x.gif", "unknown image type '.gif'");
  expect("devices --device accelerator", "no OpenCL accelerator device was found");
  expect("devices --device 99", "no OpenCL device 99");
}

TEST_CASE("stylerf devices reports that a CPU device flushes denormal floats") {
  // Without the mode, x86 CPUs take a slow path for every value below 1e-38: a backdrop-free scene's style
  // steps ran 1.7x slower (docs/results.md). `stylerf devices` multiplies 1e-20 by 1e-20 on the device.
  const testing::CliRun r = testing::run_cli("devices");
  REQUIRE(r.code == 0);
  // The chosen device's index, then its own line in the list ("[N] cpu ...").
  const size_t at = r.output.find("chosen: [");
  REQUIRE(at != std::string::npos);
  const std::string index = r.output.substr(at + 9, r.output.find(']', at) - at - 9);
  const bool cpu = r.output.rfind("[" + index + "] cpu ", 0) == 0 ||
                   r.output.find("\n[" + index + "] cpu ") != std::string::npos;
#if defined(__x86_64__)
  if (cpu) CHECK(r.output.find("denormals: flushed to zero") != std::string::npos);
#endif
  CHECK(r.output.find("denormals: ") != std::string::npos);
}

TEST_CASE("the library's kernels flush denormals, and the caller's thread keeps its own mode") {
  // This process never sets the mode itself: the kernels are built with -cl-denorms-are-zero
  // (host/runtime.cpp), which PoCL applies to the thread running each kernel, for that kernel only.
  // The option allows a device to flush; PoCL on x86 does (a GPU's compiler may or may not).
  const bool x86_cpu = (stylerf::host::Runtime::instance().device().type & CL_DEVICE_TYPE_CPU) != 0 &&
#if defined(__x86_64__)
                       true;
#else
                       false;
#endif
  if (x86_cpu) CHECK(stylerf::nn::device_flushes_denormals());
  volatile float tiny = 1e-20f;
  CHECK(tiny * tiny > 0.0f);  // the host thread still computes denormals after the device ran
  // And a value the device keeps: the probe's kernel is not one that always writes 0.
  stylerf::host::Tensor y = stylerf::host::Tensor::from_host(std::vector<float>{0.5f}, {1}, "y");
  stylerf::nn::axpby(1e-10f, stylerf::host::Tensor::from_host(std::vector<float>{1e-10f}, {1}, "x"), 0.0f, y);
  const float kept = y.to_host()[0];
  CHECK(kept > 0.99e-20f);
  CHECK(kept < 1.01e-20f);
}

TEST_CASE("the host-BLAS engine's flush scope gives the thread its own mode back") {
  volatile float tiny = 1e-20f;
  REQUIRE(tiny * tiny > 0.0f);  // this thread keeps denormals
  {
    stylerf::host::ScopedFlushDenormals flush;
#if defined(__x86_64__)
    CHECK(tiny * tiny == 0.0f);  // flushed inside the scope
#endif
  }
  CHECK(tiny * tiny > 0.0f);  // and kept again after it
}
