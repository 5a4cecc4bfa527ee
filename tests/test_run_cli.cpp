// `stylerf run` end to end on a tiny generated scene: every step's output, summary.json and index.html,
// resuming (a second run keeps every step; a changed option reruns its step and what reads it), the
// --minutes plan (a measured frame sizes the evaluation; a resumed run plans the same), and bad input
// refused before any work. Every stage trains a fixed number of iterations (--stage-iters): what a run
// does never depends on how fast this machine is.
#include <doctest/doctest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "tests/cli_runner.hpp"
#include "tests/small_scene.hpp"

using namespace stylerf;
namespace fs = std::filesystem;

namespace {

struct Inputs {
  fs::path scene, styles;
};

// A 32 px scene of 20 views and 8 generated styles, made by the tool itself. The density stage gets 150
// iterations: in 2 s (~20) it learned no surface, and the consistency table had no valid pixel to score.
const Inputs& inputs() {
  static const Inputs in = [] {
    const fs::path root = testing::small_work_dir() / "run_inputs";
    fs::remove_all(root);
    fs::create_directories(root);
    auto r = testing::run_cli("make-scene -o '" + (root / "scene").string() + "' --size 32 --num-views 20");
    INFO(r.output);
    REQUIRE(r.code == 0);
    r = testing::run_cli("demo-images -o '" + root.string() + "' --num-styles 8 --size 64");
    INFO(r.output);
    REQUIRE(r.code == 0);
    return Inputs{root / "scene", root / "styles"};
  }();
  return in;
}

std::string run_args(const fs::path& out, int holdout) {
  const auto& in = inputs();
  return "run --scene '" + in.scene.string() + "' --styles '" + in.styles.string() + "' -o '" + out.string() +
         "' --holdout-styles " + std::to_string(holdout) +
         " --stage-iters 150,20,6 --frames 3 --eval-views 1 --table-frames 8 --max-videos 1";
}

int count(const std::string& text, const std::string& needle) {
  int n = 0;
  for (size_t p = text.find(needle); p != std::string::npos; p = text.find(needle, p + 1)) ++n;
  return n;
}

}  // namespace

TEST_CASE("run: the whole pipeline, its report, and resuming") {
  const fs::path out = testing::small_work_dir() / "run_out";
  fs::remove_all(out);
  auto r = testing::run_cli(run_args(out, 2));
  INFO(r.output);
  REQUIRE(r.code == 0);
  for (const char* f : {"density.ckpt", "features.ckpt", "style.ckpt", "density_test/metrics.json",
                        "features_test/metrics.json", "style_eval.json", "videos/metrics.json", "mix/mix_grid.png",
                        "consistency/table.json", "summary.json", "index.html", "steps.json", "logs/style.log"})
    CHECK_MESSAGE(fs::exists(out / f), f);
  const auto s = testing::read_json(out / "summary.json");
  CHECK(s["recipe"] == "fast");
  CHECK(s["stages"]["density"]["test_psnr"].is_number());
  CHECK(s["style_loss_ratio"].get<double>() > 0);
  CHECK(s["per_style"].size() == 2);  // the two held-out styles
  // Style and content together: the content loss and the structure score (LPIPS to the true view) beside
  // the style loss, on average and per style, each a measured positive ratio.
  for (const char* k : {"content_loss_ratio", "structure_lpips_ratio", "max_content_loss_ratio", "max_structure_lpips_ratio"}) {
    CAPTURE(k);
    REQUIRE(s[k].is_number());
    CHECK(s[k].get<double>() > 0);
  }
  for (const auto& st : s["per_style"]) {
    REQUIRE(st["structure_lpips_ratio"].is_number());
    CHECK(st["structure_lpips_ratio"].get<double>() <= s["max_structure_lpips_ratio"].get<double>());
  }
  // The held-out renders that feed only the report use --eval-views' views, not the whole test split.
  CHECK(testing::read_json(out / "density_test/metrics.json")["views"].size() == 1);
  CHECK(testing::read_json(out / "features_test/metrics.json")["views"].size() == 1);
  CHECK(s["consistency"]["short_rmse_ratio"].get<double>() > 0);
  CHECK(s["consistency"]["lpips_net"] == "alex");  // eval table's default trunk, named beside its ratios
  CHECK(s["mix_corner_min_mean_abs_diff"].get<double>() >= 0);
  CHECK(s["checks"].size() == 3);
  std::ifstream page(out / "index.html");
  const std::string html((std::istreambuf_iterator<char>(page)), std::istreambuf_iterator<char>());
  CHECK(html.find("mix/mix_grid.png") != std::string::npos);
  CHECK(html.find("video.mp4") != std::string::npos);
  CHECK(html.find("LPIPS to the true view") != std::string::npos);
  CHECK(html.find("per_frame_rmse.svg") != std::string::npos);
  // What a person reads: the scene's name as the title, which way each number is better, the decoded test
  // views, each held-out style's image beside its results, and what made the run.
  CHECK(html.find("<title>StyleRF: scene</title>") != std::string::npos);
  CHECK(html.find("lower is better") != std::string::npos);
  CHECK(html.find("higher is better") != std::string::npos);
  CHECK(html.find("features_test/test_000.png") != std::string::npos);
  const std::string held_out = s["per_style"][0]["style"].get<std::string>();
  CHECK(html.find("styles/" + held_out + ".png") != std::string::npos);
  CHECK(s["scene_name"] == "scene");
  CHECK(s["command_line"].get<std::string>().rfind("stylerf run --scene ", 0) == 0);
  CHECK(s["command_line"].get<std::string>().find(out.string()) != std::string::npos);
  CHECK(!s["device"]["name"].get<std::string>().empty());
  CHECK(!s["build"]["version"].get<std::string>().empty());
  CHECK(s["recipe_settings"]["feature_profile"] == "fast");
  CHECK(html.find(s["device"]["name"].get<std::string>()) != std::string::npos);
  // Depth EXRs in a subfolder: the test views' folder holds what a person opens.
  CHECK(fs::exists(out / "features_test/depth/test_000_depth.exr"));
  for (const auto& e : fs::directory_iterator(out / "features_test")) CHECK(e.path().extension() != ".exr");
  const auto style_s = testing::read_json(out / "steps.json")["style"]["seconds"].get<double>();

  // The same command again: every step is kept, none runs.
  r = testing::run_cli(run_args(out, 2));
  INFO(r.output);
  REQUIRE(r.code == 0);
  CHECK(count(r.output, "done in an earlier run") == 9);
  CHECK(count(r.output, ": stylerf ") == 0);
  CHECK(testing::read_json(out / "steps.json")["style"]["seconds"].get<double>() == style_s);

  // Another held-out split: the style stage and what reads it run again; density and features are kept.
  r = testing::run_cli(run_args(out, 3));
  INFO(r.output);
  REQUIRE(r.code == 0);
  CHECK(r.output.find("== density: done in an earlier run") != std::string::npos);
  CHECK(r.output.find("== features: done in an earlier run") != std::string::npos);
  CHECK(r.output.find("== style: stylerf train-style") != std::string::npos);
  CHECK(testing::read_json(out / "summary.json")["per_style"].size() == 3);
}

TEST_CASE("run --minutes: the evaluation planned from a measured frame, the same plan on resume") {
  const fs::path out = testing::small_work_dir() / "run_minutes";
  fs::remove_all(out);
  // The planning path of --minutes (frame probe, predicted evaluation, plan in summary.json) with the
  // stages' lengths in iterations. The budget is generous so that the plan cuts nothing whatever the
  // measured seconds: they are recorded, but do not decide pass or fail.
  const std::string cmd = run_args(out, 2) + " --minutes 600";
  auto r = testing::run_cli(cmd);
  INFO(r.output);
  REQUIRE(r.code == 0);
  CHECK(fs::exists(out / "probe/frames/metrics.json"));
  CHECK(r.output.find("evaluation predicted") != std::string::npos);
  const auto steps = testing::read_json(out / "steps.json");
  CHECK(steps.contains("probe_style"));
  CHECK(steps.contains("probe_frames"));
  const auto summary = testing::read_json(out / "summary.json");
  REQUIRE(summary.contains("plan"));
  CHECK(summary["plan"]["frame_content_s"].get<double>() > 0);
  CHECK(summary["plan"]["frame_rgb_s"].get<double>() > 0);  // the density_test render timed its views
  CHECK(summary["plan"]["style_minutes"].get<double>() > 0);
  CHECK(summary["plan"]["style_iters"] == 6);  // --stage-iters' style length, kept under the plan
  CHECK(summary["plan"]["cuts"] == "");
  CHECK(r.output.find("the style stage trains its 6 iterations (--stage-iters)") != std::string::npos);
  // The rays a block the probe's frames took, read off their metrics: the recipe's 3x3 on this small scene.
  CHECK(summary["plan"]["frame_rays_per_block"].get<int>() == 9);

  // Resumed: the recorded seconds give the same plan, so every step keeps its key and nothing runs.
  r = testing::run_cli(cmd);
  INFO(r.output);
  REQUIRE(r.code == 0);
  CHECK(count(r.output, "done in an earlier run") == 11);
  CHECK(count(r.output, ": stylerf ") == 0);
}

TEST_CASE("run: bad input is refused before any work, naming the problem") {
  const auto& in = inputs();
  const fs::path out = testing::small_work_dir() / "run_bad";
  auto expect = [&](const std::string& args, const std::string& needle) {
    const auto r = testing::run_cli("run " + args + " -o '" + out.string() + "'");
    INFO(r.output);
    CHECK(r.code != 0);
    CHECK(r.output.find(needle) != std::string::npos);
    CHECK_FALSE(fs::exists(out / "steps.json"));
  };
  const std::string ok = "--scene '" + in.scene.string() + "' --styles '" + in.styles.string() + "'";
  expect("--scene /no/such/scene --styles '" + in.styles.string() + "'", "/no/such/scene");
  expect(ok + " --recipe quick", "recipe 'quick'");
  expect(ok + " --stage-minutes 1,2", "--stage-minutes");
  expect(ok + " --stage-iters 10,20,2.5", "whole numbers");
  expect(ok + " --stage-iters 10,20,5 --stage-minutes 1,1,1", "exclude each other");
  expect(ok + " --minutes 0", "--minutes");  // refused before any timing: no clock involved
  expect(ok + " --holdout-styles 8", "held out leaves none");
  expect(ok + " --stylize /no/such.png", "/no/such.png");
}
