// `stylerf eval consistency` and `stylerf eval table` end to end on a generated scene, as a user runs them
// (the built binary): every method gives finite scores over the right pairs, the table writes its Markdown,
// JSON, plot and side-by-side frames; bad input is refused before any work, naming what is wrong.
// `stylerf lpips` with either trunk (--lpips-net vgg | alex) and its refused inputs.
#include <doctest/doctest.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "lib/eval/consistency.hpp"
#include "lib/eval/path_consistency.hpp"
#include "lib/eval/path_frames.hpp"
#include "lib/io/checkpoint.hpp"
#include "lib/model/density_model.hpp"
#include "lib/io/image.hpp"
#include "tests/cli_runner.hpp"
#include "tests/small_scene.hpp"
#include "tests/testing.hpp"

using namespace stylerf;
namespace fs = std::filesystem;

namespace {

std::string fixture(const std::string& name) { return std::string(STYLERF_TEST_FIXTURES) + "/styles/" + name; }

testing::CliRun run(const std::string& args) { return testing::run_cli(args); }

struct Checkpoints {
  std::string density, style;
};
// A short density stage through the CLI, and the shared untrained style stage over the small geometry
// (the plumbing is under test here, not the quality).
const Checkpoints& checkpoints() {
  static Checkpoints c = [] {
    const scene::Scene& sc = testing::small_scene();
    Checkpoints out;
    out.density = (testing::small_work_dir() / "eval_density.ckpt").string();
    // 60 steps of the default 4096 rays; under STYLERF_TEST_SMALL (the simulator) 20 steps of 256.
    const std::string schedule = testing::small_run() ? "--iters 20 --batch 256 --upsample-at 12 --mask-at 12"
                                                      : "--iters 60 --upsample-at 40 --mask-at 40";
    const auto r = run("train-density --scene '" + sc.root + "' " + schedule +
                       " --init-voxels 24^3 --final-voxels 32^3 --density-rank 8,8,8 --app-rank 8,8,8 --eval-views 1 "
                       "--force -o '" + out.density + "'");
    REQUIRE_MESSAGE(r.code == 0, r.output);
    // The shared untrained style stage, with two held-out styles recorded (eval table's default styles).
    io::Checkpoint ck = io::load_checkpoint(testing::small_stage_files().style, "style");
    ck.meta["styles"] = {{"train", nlohmann::json::array()}, {"holdout", {fixture("cmyk.jpg"), fixture("rgb16.png")}}};
    out.style = (testing::small_work_dir() / "eval_style.ckpt").string();
    io::save_checkpoint(out.style, ck);
    return out;
  }();
  return c;
}

using testing::read_json;

// The JSON's pair counts, and each range's scores recomputed here from its own pairs as docs/design.md
// defines them: the mean over the pairs with valid pixels (null scores), the count of the others, the
// valid fraction's mean over all pairs.
void check_score(const nlohmann::json& score, bool lpips) {
  CHECK(score["short"]["pairs"].size() == 15);  // 16 frames: t = 1..15 into t-1
  CHECK(score["long"]["pairs"].size() == 9);    // t = 7..15 into t-7
  for (const char* r : {"short", "long"}) {
    CAPTURE(r);
    double rmse_sum = 0, lpips_sum = 0, valid_sum = 0;
    int counted = 0, empty = 0;
    for (const auto& p : score[r]["pairs"]) {
      valid_sum += double(p["valid_fraction"]);
      if (p["rmse"].is_null()) {
        ++empty;
        continue;
      }
      ++counted;
      rmse_sum += double(p["rmse"]);
      if (lpips) lpips_sum += double(p["lpips"]);
    }
    REQUIRE(counted > 0);  // the geometry left something to compare
    CHECK(score[r]["skipped"] == empty);
    CHECK(double(score[r]["rmse"]) == doctest::Approx(rmse_sum / counted).epsilon(1e-12));
    CHECK(double(score[r]["valid_fraction"]) ==
          doctest::Approx(valid_sum / double(score[r]["pairs"].size())).epsilon(1e-12));
    if (lpips)
      CHECK(double(score[r]["lpips"]) == doctest::Approx(lpips_sum / counted).epsilon(1e-12));
    else
      CHECK(score[r]["lpips"].is_null());
  }
}

// The library's RMSE-only score of the rgb method on the default path (16 of 120 frames, the scene's size),
// computed here as cmd_eval does it: what `eval consistency --method rgb` must report.
eval::ConsistencyScore library_rgb_score(const std::string& density_ckpt) {
  const model::DensityModel m = model::load_model(io::load_checkpoint(density_ckpt, "density"));
  const scene::Scene& scene = testing::small_scene();
  const eval::PathOptions p;
  const eval::PathSetup setup = eval::path_setup(m.geo, scene, p);
  return eval::score_frames(eval::rgb_frames(m, scene, setup.cams, p.chunk), setup.warps, nullptr);
}

}  // namespace

TEST_CASE("eval consistency: rgb, adain and stylerf on a generated scene") {
  const auto& ck = checkpoints();
  const fs::path dir = testing::small_work_dir() / "eval_cli";
  fs::create_directories(dir);
  auto r = run("eval consistency --ckpt '" + ck.density + "' --method rgb --json '" + (dir / "rgb.json").string() +
               "' -o '" + (dir / "rgb").string() + "'");
  REQUIRE_MESSAGE(r.code == 0, r.output);
  const auto rgb = read_json(dir / "rgb.json");
  check_score(rgb["score"], true);
  CHECK(fs::exists(dir / "rgb" / "frame_015.png"));
  // The command's numbers are the library's on the same checkpoint, pair by pair.
  const eval::ConsistencyScore lib = library_rgb_score(ck.density);
  CHECK(double(rgb["score"]["short"]["rmse"]) == doctest::Approx(lib.short_range.rmse).epsilon(1e-9));
  CHECK(double(rgb["score"]["long"]["rmse"]) == doctest::Approx(lib.long_range.rmse).epsilon(1e-9));
  for (size_t i = 0; i < lib.short_range.pairs.size(); ++i) {
    CAPTURE(i);
    CHECK(double(rgb["score"]["short"]["pairs"][i]["valid_fraction"]) == lib.short_range.pairs[i].valid_fraction);
    if (!std::isnan(lib.short_range.pairs[i].rmse))
      CHECK(double(rgb["score"]["short"]["pairs"][i]["rmse"]) ==
            doctest::Approx(lib.short_range.pairs[i].rmse).epsilon(1e-9));
  }

  // The default trunk is AlexNet; VGG-16 gives another LPIPS and the same RMSE.
  r = run("eval consistency --ckpt '" + ck.density + "' --method rgb --lpips-net vgg --json '" +
          (dir / "rgb_vgg.json").string() + "'");
  REQUIRE_MESSAGE(r.code == 0, r.output);
  const auto vgg = read_json(dir / "rgb_vgg.json");
  check_score(vgg["score"], true);
  CHECK(vgg["score"]["short"]["rmse"] == rgb["score"]["short"]["rmse"]);
  CHECK(vgg["score"]["short"]["lpips"] != rgb["score"]["short"]["lpips"]);
  CHECK(rgb["lpips"].get<std::string>().rfind("alex ", 0) == 0);
  CHECK(vgg["lpips"].get<std::string>().rfind("vgg ", 0) == 0);

  r = run("eval consistency --ckpt '" + ck.density + "' --method adain --style '" + fixture("cmyk.jpg") +
          "' --no-lpips --json '" + (dir / "adain.json").string() + "'");
  REQUIRE_MESSAGE(r.code == 0, r.output);
  const auto adain = read_json(dir / "adain.json");
  check_score(adain["score"], false);
  // The same geometry decides what is compared, whatever the method.
  CHECK(adain["score"]["short"]["valid_fraction"] == rgb["score"]["short"]["valid_fraction"]);

  r = run("eval consistency --ckpt '" + ck.style + "' --method stylerf --style '" + fixture("rgb16.png") +
          "' --no-lpips --scored-frames 10 --json '" + (dir / "stylerf.json").string() + "'");
  REQUIRE_MESSAGE(r.code == 0, r.output);
  const auto sr = read_json(dir / "stylerf.json");
  CHECK(sr["score"]["short"]["pairs"].size() == 9);
  CHECK(sr["score"]["long"]["pairs"].size() == 3);
}

TEST_CASE("eval table: Markdown, JSON, plot and side-by-side frames") {
  const auto& ck = checkpoints();
  const fs::path dir = testing::small_work_dir() / "eval_table";
  // Two groups: the second, without a style stage, is scored on the first one's held-out styles.
  const auto r = run("eval table --scene-ckpts '" + ck.density + "," + ck.style + "' '" + ck.density +
                     "' --scored-frames 9 --path-frames 60 -o '" + dir.string() + "'");
  REQUIRE_MESSAGE(r.code == 0, r.output);
  const auto table = read_json(dir / "table.json");
  REQUIRE(table["scenes"].size() == 2);
  REQUIRE(table["scenes"][1]["methods"].size() == 2);
  CHECK(table["scenes"][1]["methods"][1]["per_style"].size() == 2);
  const auto& methods = table["scenes"][0]["methods"];
  REQUIRE(methods.size() == 3);
  CHECK(methods[0]["method"] == "RGB (unstylised floor)");
  CHECK(methods[1]["method"] == "AdaIN (per frame)");
  CHECK(methods[2]["method"].get<std::string>().rfind("StyleRF (", 0) == 0);  // named by its file
  CHECK(methods[1]["per_style"].size() == 2);  // the style checkpoint's two held-out styles
  // The table's RGB row is `eval consistency --method rgb` on the same path: its warps come from the RGB
  // render's own depth and opacity there, from a separate geometry render here, and must agree.
  const fs::path rgb_json = dir.parent_path() / "eval_table_rgb.json";
  const auto single = run("eval consistency --ckpt '" + ck.density + "' --method rgb --scored-frames 9 --path-frames 60 --json '" +
                          rgb_json.string() + "'");
  REQUIRE_MESSAGE(single.code == 0, single.output);
  const auto rgb = read_json(rgb_json)["score"];
  for (const char* range : {"short", "long"}) {
    CAPTURE(range);
    CHECK(double(methods[0][range]["rmse"]) == doctest::Approx(double(rgb[range]["rmse"])).epsilon(1e-9));
    CHECK(double(methods[0][range]["lpips"]) == doctest::Approx(double(rgb[range]["lpips"])).epsilon(1e-9));
    for (const auto& m : methods) {  // every method scored (null would be a range without a valid pair)
      CHECK(m[range]["rmse"].is_number());
      CHECK(m[range]["lpips"].is_number());
    }
  }
  std::ifstream md(dir / "table.md");
  const std::string text((std::istreambuf_iterator<char>(md)), std::istreambuf_iterator<char>());
  CHECK(text.find("| AdaIN (per frame) |") != std::string::npos);
  CHECK(text.find(" / AdaIN: short RMSE") != std::string::npos);
  const std::string scene_name = testing::small_scene().name;
  std::ifstream svg_file(dir / scene_name / "per_frame_rmse.svg");
  const std::string svg((std::istreambuf_iterator<char>(svg_file)), std::istreambuf_iterator<char>());
  CHECK(svg.rfind("<svg", 0) == 0);
  for (const char* label : {"RGB (unstylised floor)", "AdaIN (per frame)", "StyleRF", "frame pair", "RMSE"})
    CHECK_MESSAGE(svg.find(label) != std::string::npos, label);
  CHECK(fs::exists(dir / (scene_name + "_2") / "per_frame_rmse.svg"));  // the second group's, beside it
  const auto pair = io::load_image((dir / scene_name / "side_by_side" / "frame_0000.png").string());
  CHECK(pair.width == 2 * testing::small_scene().width());
}

TEST_CASE("eval style --vgg-map-row: the style module on the true views' own VGG maps, beside the rendered row") {
  const auto& ck = checkpoints();
  const fs::path dir = testing::small_work_dir() / "eval_style_vgg_map";
  fs::create_directories(dir);
  const auto with = run("eval style --ckpt '" + ck.style + "' --max-views 1 --vgg-map-row --json '" +
                        (dir / "with.json").string() + "'");
  REQUIRE_MESSAGE(with.code == 0, with.output);
  CHECK(with.output.find("ours on the true views' VGG maps (no radiance field) / AdaIN: style loss") != std::string::npos);
  const auto j = read_json(dir / "with.json");
  REQUIRE(j.contains("on_vgg_maps"));
  for (const char* k : {"style_loss_ratio", "content_loss_ratio"}) {
    CAPTURE(k);
    const double v = j["on_vgg_maps"][k].get<double>();
    CHECK(std::isfinite(v));
    CHECK(v > 0);
    CHECK(v != j[k].get<double>());  // a different input than the rendered map
  }
  const auto without = run("eval style --ckpt '" + ck.style + "' --max-views 1 --json '" + (dir / "without.json").string() + "'");
  REQUIRE_MESSAGE(without.code == 0, without.output);
  const auto k = read_json(dir / "without.json");
  CHECK_FALSE(k.contains("on_vgg_maps"));
  CHECK(k["style_loss_ratio"] == j["style_loss_ratio"]);  // the rendered row is the same either way
}

TEST_CASE("eval: bad input is refused before any work, naming the problem") {
  const auto& ck = checkpoints();
  auto expect = [](const std::string& args, const std::string& needle) {
    const auto r = run(args);
    INFO(args << "\n" << r.output);
    CHECK(r.code != 0);
    CHECK(r.output.find(needle) != std::string::npos);
  };
  expect("eval", "consistency|table");
  expect("eval flow", "unknown 'flow'");
  expect("eval consistency --ckpt '" + ck.density + "' --method flow", "--method must be rgb, adain or stylerf");
  expect("eval consistency --ckpt '" + ck.density + "' --method adain", "needs --style");
  expect("eval consistency --ckpt '" + ck.density + "' --method rgb --scored-frames 5", "--scored-frames must be in [8, 1000]");
  expect("eval consistency --ckpt '" + ck.density + "' --method rgb --depth-tol 0", "--depth-tol");
  expect("eval consistency --ckpt '" + ck.density + "' --method rgb --supersample -1", "--supersample: supersample '-1': expected 1..8");
  expect("eval table --scene-ckpts '" + ck.density + "' --supersample quincunx2 -o /tmp/x", "or quincunx");
  expect("eval consistency --ckpt '" + ck.density + "' --method rgb --lpips-net squeeze", "unknown net 'squeeze'");
  expect("eval consistency --ckpt '" + ck.density + "' --method stylerf --style '" + fixture("cmyk.jpg") + "'",
         "needs a style checkpoint");
  expect("eval consistency --ckpt '" + ck.style + "' --method rgb", "needs a density checkpoint");
  expect("eval consistency --ckpt '" + ck.density + "' --method adain --style /nonexistent.png", "/nonexistent.png");
  expect("eval table --scene-ckpts '" + ck.style + "' -o /tmp/x", "must be a density checkpoint");
  expect("eval table --scene-ckpts '" + ck.density + "' -o '" + (testing::small_work_dir() / "t2").string() + "'",
         "--styles is needed");
  expect("eval table --scene-ckpts /nonexistent.ckpt -o /tmp/x", "/nonexistent.ckpt is not a file");
}

TEST_CASE("lpips: --lpips-net vgg and alex print the distance; bad input names the problem") {
  const fs::path dir = testing::small_work_dir() / "lpips_cli";
  fs::create_directories(dir);
  auto image = [&](const std::string& name, int w, int h, float phase) {
    io::Image im{w, h, std::vector<float>(size_t(3) * w * h)};
    for (int c = 0; c < 3; ++c)
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) im.at(c, y, x) = 0.5f + 0.4f * std::sin(0.3f * x + 0.2f * y * (c + 1) + phase);
    const std::string path = (dir / name).string();
    io::save_png(path, im);
    return "'" + path + "'";
  };
  const std::string a = image("a.png", 48, 40, 0.0f), b = image("b.png", 48, 40, 1.0f);
  const std::string small = image("small.png", 40, 30, 0.0f);
  for (const std::string net : {"vgg", "alex"}) {
    CAPTURE(net);
    auto r = run("lpips " + a + " " + b + " --lpips-net " + net);
    INFO(r.output);
    REQUIRE(r.code == 0);
    const double d = std::stod(r.output);
    CHECK(d > 0.0);
    CHECK(d < 2.0);
    r = run("lpips " + a + " " + a + " --lpips-net " + net);
    REQUIRE(r.code == 0);
    CHECK(std::stod(r.output) == 0.0);
  }
  auto expect = [](const std::string& args, const std::string& needle) {
    const auto r = run(args);
    INFO(args << "\n" << r.output);
    CHECK(r.code != 0);
    CHECK(r.output.find(needle) != std::string::npos);
  };
  expect("lpips " + small + " " + small + " --lpips-net alex", "are 40x30: LPIPS (--lpips-net alex) needs at least 31x31");
  CHECK(run("lpips " + small + " " + small + " --lpips-net vgg").code == 0);  // VGG takes 16x16 and up
  expect("lpips " + small + " " + small, "needs at least 31x31");  // AlexNet is the default
  expect("lpips " + a + " " + small + " --lpips-net alex", "is 48x40 but");
  expect("lpips " + a + " " + b + " --lpips-net squeeze", "--lpips-net squeeze: unknown trunk (use vgg or alex)");
}

TEST_CASE("bench render: seconds per view and per step for each --ert, per-kernel breakdown, JSON") {
  const auto json_path = testing::small_work_dir() / "bench_render.json";
  const auto r = run("bench render --ckpt '" + checkpoints().density + "' --max-views 2 --steps 2 --ert 0,1e-4 --json '" +
                     json_path.string() + "'");
  INFO(r.output);
  REQUIRE(r.code == 0);
  CHECK(r.output.find("early termination off") != std::string::npos);
  CHECK(r.output.find("s/view") != std::string::npos);
  CHECK(r.output.find("s/step") != std::string::npos);
  const auto j = read_json(json_path);
  REQUIRE(j["rows"].size() == 2);
  for (const auto& row : j["rows"]) {
    CHECK(double(row["render"]["s_per_view"]) > 0);
    CHECK(double(row["render"]["psnr"]) > 10);
    CHECK(double(row["train"]["s_per_step"]) > 0);
    CHECK(double(row["train"]["samples_per_ray"]) > 0);
    CHECK(row["render"]["kernel_s_per_view"].size() > 3);
  }
  // The same model renders the same views whether or not rays stop early (the samples past a stop weigh
  // less than 1e-4).
  CHECK(double(j["rows"][0]["render"]["psnr"]) == doctest::Approx(double(j["rows"][1]["render"]["psnr"])).epsilon(1e-3));
  CHECK(double(j["rows"][1]["train"]["samples_per_ray"]) <= double(j["rows"][0]["train"]["samples_per_ray"]));
}
