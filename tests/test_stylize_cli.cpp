// `stylerf stylize` end to end on a generated scene, as a user runs it (the built binary, through a shell):
//  - a style never trained on along a path: PNG frames, depth EXRs, metrics.json with the timings and
//    finite per-view losses; test views add the 2D AdaIN losses; --mix, --mix-grid and --region outputs;
//  - bad input, each a clear error (exit code 1, a message naming the problem) and nothing half-written:
//    a stage-2 checkpoint (no stylizer), another scene's folder, a folder without images, mix weights that
//    do not match, a region without its two styles;
//  - hard style images (1x1 grey, CMYK JPEG) give finite images.
#include <doctest/doctest.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>

#include "lib/io/exr.hpp"
#include "lib/io/image.hpp"
#include "lib/scene/make_scene.hpp"
#include "tests/cli_runner.hpp"
#include "tests/small_scene.hpp"
#include "tests/testing.hpp"

using namespace stylerf;
namespace fs = std::filesystem;

namespace {

std::string fixture(const std::string& name) { return std::string(STYLERF_TEST_FIXTURES) + "/styles/" + name; }

using Run = testing::CliRun;
Run stylerf_cli(const std::string& args) { return testing::run_cli(args); }

using Checkpoints = testing::SmallStageFiles;
const Checkpoints& checkpoints() { return testing::small_stage_files(); }

using testing::read_json;

bool finite_png(const fs::path& p) {
  const io::Image img = io::load_image(p.string());
  return img.width > 0 && testing::all_finite(img.data);
}

}  // namespace

TEST_CASE("stylize: a path, test views with the AdaIN baseline, mix, sheet and region") {
  const auto& ck = checkpoints();
  const fs::path out = testing::small_work_dir() / "cli_path";
  Run r = stylerf_cli("stylize --ckpt '" + ck.style + "' --style '" + fixture("rgb16.png") +
                      "' --views path --frames 3 --cache none -o '" + out.string() + "'");
  INFO(r.output);
  REQUIRE(r.code == 0);
  for (int i = 0; i < 3; ++i) {
    CHECK(finite_png(out / ("frame_000" + std::to_string(i) + ".png")));
    CHECK(fs::exists(out / "depth" / ("depth_000" + std::to_string(i) + ".exr")));
  }
  nlohmann::json m = read_json(out / "metrics.json");
  CHECK(m["timing"]["first_frame_s"].get<double>() > 0);
  CHECK(m["timing"]["frames"].get<int>() == 3);
  CHECK(m["per_view"].size() == 3);
  for (const auto& v : m["per_view"])
    for (const auto& [name, l] : v["styles"].items()) {
      CHECK(l["content"].is_number());
      CHECK(l["style"].is_number());
    }

  const fs::path test_out = testing::small_work_dir() / "cli_test";
  r = stylerf_cli("stylize --ckpt '" + ck.style + "' --style '" + fixture("rgb16.png") + "' --style '" +
                  fixture("cmyk.jpg") + "' --views test --max-views 2 --size 40 -o '" + test_out.string() + "'");
  INFO(r.output);
  REQUIRE(r.code == 0);
  m = read_json(test_out / "metrics.json");
  CHECK(m["size"][0].get<int>() == 40);
  for (const auto& [name, l] : m["mean_losses"].items()) {
    CHECK(l["adain_style"].is_number());
    CHECK(l["style_ratio_ours_over_adain"].is_number());
  }
  CHECK(fs::exists(test_out / "rgb16"));
  CHECK(fs::exists(test_out / "cmyk"));

  const fs::path mix_out = testing::small_work_dir() / "cli_mix";
  r = stylerf_cli("stylize --ckpt '" + ck.style + "' --style '" + fixture("rgb16.png") + "' --style '" +
                  fixture("grey1x1.png") + "' --mix 0.25,0.75 --views path --frames 2 -o '" + mix_out.string() + "'");
  INFO(r.output);
  CHECK(r.code == 0);
  CHECK(finite_png(mix_out / "frame_0001.png"));

  const fs::path grid_out = testing::small_work_dir() / "cli_grid";
  r = stylerf_cli("stylize --ckpt '" + ck.style + "' --views test --mix-grid '" + fixture("rgb16.png") + "," +
                  fixture("grey1x1.png") + "," + fixture("cmyk.jpg") + "," + fixture("rgb16.png") + "' -o '" +
                  grid_out.string() + "'");
  INFO(r.output);
  CHECK(r.code == 0);
  const io::Image sheet = io::load_image((grid_out / "mix_grid.png").string());
  CHECK(sheet.width == 5 * 48);

  const fs::path reg_out = testing::small_work_dir() / "cli_region";
  r = stylerf_cli("stylize --ckpt '" + ck.style + "' --region sphere:0,0,0,0.5 --style-inside '" + fixture("rgb16.png") +
                  "' --style-outside '" + fixture("grey1x1.png") + "' --views path --frames 2 --no-losses -o '" +
                  reg_out.string() + "'");
  INFO(r.output);
  CHECK(r.code == 0);
  CHECK(finite_png(reg_out / "mask_0000.png"));
  CHECK(finite_png(reg_out / "frame_0001.png"));
}

TEST_CASE("stylize: bad input gets a clear error") {
  const auto& ck = checkpoints();
  const std::string style = fixture("rgb16.png");
  const std::string out = (testing::small_work_dir() / "cli_bad").string();
  auto expect = [&](const std::string& args, const std::string& needle) {
    const Run r = stylerf_cli(args);
    INFO(args);
    INFO(r.output);
    CHECK(r.code == 1);
    CHECK(r.output.find(needle) != std::string::npos);
  };
  expect("stylize --ckpt '" + ck.features + "' --style '" + style + "' -o '" + out + "'", "not a trained stylizer");
  expect("stylize --ckpt '" + ck.style + "' --style '" + style + "' --supersample 9 -o '" + out + "'",
         "--supersample: supersample '9': expected 1..8 (n x n rays a block) or quincunx");
  // Another scene: same format, other name.
  const std::string other = (testing::small_work_dir() / "other_scene").string();
  {
    scene::MakeSceneOptions mo;
    mo.size = 32;
    mo.views = 8;
    scene::make_scene(other, mo);
  }
  expect("stylize --ckpt '" + ck.style + "' --style '" + style + "' --scene '" + other + "' -o '" + out + "'",
         "was trained on scene");
  const fs::path empty_dir = testing::small_work_dir() / "no_images";
  fs::create_directories(empty_dir);
  std::ofstream((empty_dir / "readme.png").string()) << "not an image";
  expect("stylize --ckpt '" + ck.style + "' --style '" + empty_dir.string() + "' -o '" + out + "'", "no readable image");
  expect("stylize --ckpt '" + ck.style + "' --style '" + (empty_dir / "readme.png").string() + "' -o '" + out + "'",
         "readme.png");
  expect("stylize --ckpt '" + ck.style + "' --style '" + style + "' --style '" + style + "' --mix 0.5 -o '" + out + "'",
         "1 weights for 2 styles");
  expect("stylize --ckpt '" + ck.style + "' --style '" + style + "' --mix 2 -o '" + out + "'", "sum to 1");
  expect("stylize --ckpt '" + ck.style + "' --region sphere:0,0,0,1 --style-inside '" + style + "' -o '" + out + "'",
         "--style-outside");
  expect("stylize --ckpt '" + ck.style + "' --style '" + style + "' --views test --size -3 -o '" + out + "'", "--size");
  expect("stylize --ckpt '" + ck.style + "' --region cube:1 --style-inside '" + style + "' --style-outside '" + style +
             "' -o '" + out + "'",
         "unknown kind 'cube'");
  expect("stylize --ckpt '" + ck.style + "' --style '" + style + "' --style-inside '" + style + "' -o '" + out + "'",
         "need --region");
  // The buffer pool's cap from the environment: a typo is an error naming the variable, not a silent default.
  setenv("STYLERF_POOL_MIB", "4GB", 1);
  expect("stylize --ckpt '" + ck.style + "' --style '" + style + "' -o '" + out + "'", "STYLERF_POOL_MIB='4GB'");
  unsetenv("STYLERF_POOL_MIB");
  // train-style's schedule knobs are checked before any checkpoint is read.
  const std::string train = "train-style --features '" + ck.features + "' --styles '" + empty_dir.string() + "' -o '" +
                            out + "' ";
  expect(train + "--lr-decay 0", "--lr-decay must be in (0, 1]");
  expect(train + "--lr-decay 1.5", "--lr-decay must be in (0, 1]");
  expect(train + "--warm-share 0", "--warm-share must be in (0, 1]");
  expect(train + "--decoder-warm -1", "--decoder-warm must be >= 0, got -1");
  expect(train + "--eval-every -1", "--log-every, --eval-every");
  expect(train + "--warm-maps photos", "--warm-maps must be vgg or rendered, got 'photos'");
  expect(train + "--style-decoder adain", "--style-decoder must be stage2, vgg-adain or vgg-adain-relu4, got 'adain'");
  expect(train + "--lr-decoder -1", "--lr-decoder must be a positive number");
  expect(train + "--lr-decoder 0", "--lr-decoder must be a positive number");
  expect(train + "--lr-stylizer 0", "--lr-stylizer must be a positive number");
  expect(train + "--content-weight 0", "--content-weight must be a positive number");
  expect(train + "--content-weight -3", "--content-weight must be a positive number");
  expect(train + "--style-size 128", "--style-size must be in [256, 4096] (the crop is 256), got 128");
  expect(train + "--patch 12", "--patch must be a positive multiple of 8, got 12");
  expect(train + "--iters 0", "--iters must be >= 1, got 0");
  CHECK_FALSE(fs::exists(out));  // every refusal came before anything was written
}
