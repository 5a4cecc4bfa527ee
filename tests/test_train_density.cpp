// The density stage end to end on a generated scene (make-scene, known depth): the schedule, the training
// loop (loss falls, learned depth close to the truth), checkpoints (round trip, resume, corrupt/wrong files,
// no half-written file) and the NaN guard. Small sizes throughout: the whole file is meant to run in
// well under two minutes on a loaded 2-core CPU.
#include <doctest/doctest.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <sstream>
#include <iostream>
#include <unistd.h>

#include "host/error.hpp"
#include "lib/io/exr.hpp"
#include "lib/scene/make_scene.hpp"
#include "lib/train/density_trainer.hpp"
#include "lib/train/stage_programs.hpp"
#include "tests/testing.hpp"

using namespace stylerf;
namespace fs = std::filesystem;

namespace {

fs::path work_dir() {
  static fs::path dir = [] {
    fs::path d = fs::temp_directory_path() / ("stylerf_test_train_" + std::to_string(::getpid()));
    fs::remove_all(d);
    fs::create_directories(d);
    return d;
  }();
  return dir;
}

const scene::Scene& small_scene() {
  static scene::Scene s = [] {
    scene::MakeSceneOptions mo;
    mo.size = 40;
    mo.views = 30;  // 24 train, 3 val, 3 test
    const std::string dir = (work_dir() / "scene").string();
    scene::make_scene(dir, mo);
    return scene::load_scene(dir);
  }();
  return s;
}

// The final grid by scene kind and recipe: a camera of 504 px (above the small-image rule) on a scene that
// only differs in its format string and NDC flag.
TEST_CASE("final grid in the fast recipe: 400^3 for NDC scenes, 300^3 for objects; TensoRF's 640^3 in the paper's") {
  scene::Scene s = small_scene();
  for (auto& v : s.train) {
    v.camera.width = 504;
    v.camera.height = 378;
  }
  auto side = [&](const std::string& format, bool paper) {
    s.format = format;
    s.effects.ndc = format.size() > 8 && format.compare(format.size() - 8, 8, "-forward") == 0;
    return int(std::lround(std::cbrt(double(train::default_density_config(s, paper).schedule.voxels_final))));
  };
  CHECK(side("llff-forward", false) == train::kFastLlffFinalSide);
  CHECK(side("colmap-forward", false) == train::kFastLlffFinalSide);
  CHECK(side("llff-forward", true) == 640);
  CHECK(side("llff-object", false) == train::kFastObjectFinalSide);
  CHECK(side("llff-object", true) == 640);
  CHECK(side("blender", false) == 300);
  CHECK(side("blender", true) == 300);
}

// A small, fast configuration with every event of the TensoRF schedule inside the run: one alpha-mask
// update (with the box shrink) and one upsample at step 60.
train::DensityTrainConfig small_config(int iters) {
  auto cfg = train::default_density_config(small_scene());
  cfg.model.density_rank = {8, 8, 8};
  cfg.model.app_rank = {12, 12, 12};
  cfg.model.hidden = 64;
  cfg.schedule.iters = iters;
  cfg.schedule.voxels_init = 24 * 24 * 24;
  cfg.schedule.voxels_final = 40 * 40 * 40;
  cfg.schedule.upsample_at = {60};
  cfg.schedule.mask_at = {60};
  // 128 rays a step under STYLERF_TEST_SMALL (the simulator): the schedule and NaN-guard cases count steps,
  // not rays; the cases that judge the trained model's quality are skipped there (scripts/oclgrind.sh).
  cfg.batch = testing::small_run() ? 128 : 1024;
  cfg.seed = 3;
  // relu (StyleRF's configs) rather than TensoRF's shifted softplus: opaque from the start, so 150 short
  // steps get further.
  cfg.model.act = field::DensityActivation::Relu;
  return cfg;
}

struct Trained {
  std::unique_ptr<train::DensityTrainer> trainer;
  double first_mse = 0, last_mse = 0;
  std::vector<train::StepStats> stats;
};

// Trains once per process (shared by the test cases that need a trained model).
Trained& trained() {
  static Trained t = [] {
    Trained r;
    const auto t0 = std::chrono::steady_clock::now();  // printed below, never checked
    r.trainer = std::make_unique<train::DensityTrainer>(small_scene(), small_config(150));
    while (!r.trainer->done()) r.stats.push_back(r.trainer->step());
    double a = 0, b = 0;
    for (int i = 0; i < 5; ++i) a += r.stats[size_t(i)].mse, b += r.stats[r.stats.size() - 1 - size_t(i)].mse;
    r.first_mse = a / 5;
    r.last_mse = b / 5;
    std::cout << "trained 150 steps in " << std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count()
              << " s: batch mse " << r.first_mse << " -> " << r.last_mse << "; " << r.trainer->model().describe()
              << std::endl;
    return r;
  }();
  return t;
}

std::vector<float> host_of(const host::Tensor& t) { return t.to_host(); }

void flip_byte(const std::string& path, std::streamoff from_end) {
  std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
  f.seekg(-from_end, std::ios::end);
  char c = 0;
  f.read(&c, 1);
  c = static_cast<char>(c ^ 0x5a);
  f.seekp(-from_end, std::ios::end);
  f.write(&c, 1);
}

std::vector<std::string> files_in(const fs::path& dir) {
  std::vector<std::string> out;
  for (const auto& e : fs::directory_iterator(dir)) out.push_back(e.path().filename().string());
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace

TEST_CASE("schedule: TensoRF's voxel list, lr decay with reset, event steps") {
  train::Schedule s;  // Blender defaults: 128^3 -> 300^3 over [2000, 3000, 4000, 5500], 30000 iterations
  const auto v = s.voxel_list();
  REQUIRE(v.size() == 4);
  // round(exp(linspace(log 128^3, log 300^3, 5)))[1:], computed here independently.
  for (int i = 1; i <= 4; ++i) {
    const double want = std::exp(std::log(2097152.0) + (std::log(27000000.0) - std::log(2097152.0)) * i / 4.0);
    CHECK(v[size_t(i - 1)] == std::llround(want));
  }
  CHECK(v.back() == 27000000);
  CHECK(s.voxels_after(1999) == 2097152);
  CHECK(s.voxels_after(2000) == v[0]);
  CHECK(s.voxels_after(100000) == v[3]);
  CHECK(s.lr_scale(1) == doctest::Approx(1.0));
  // Before the first upsample: ratio^((k-1)/iters); right after one, back to 1 (TensoRF's lr_upsample_reset).
  CHECK(s.lr_scale(2000) == doctest::Approx(std::pow(0.1, 1999.0 / 30000)));
  CHECK(s.lr_scale(2001) == doctest::Approx(1.0));
  CHECK(s.lr_scale(30000) == doctest::Approx(std::pow(0.1, (29999.0 - 5500) / 30000)));
  s.lr_reset_on_upsample = false;
  CHECK(s.lr_scale(30001) == doctest::Approx(0.1));
  CHECK(s.reg_scale(30001) == doctest::Approx(0.1));
  CHECK(s.upsample_at_step(3000));
  CHECK_FALSE(s.upsample_at_step(3001));
  CHECK(s.first_mask_step(2000));
  CHECK(train::parse_int_list("2000,3000", "--x") == std::vector<int>{2000, 3000});
  CHECK(train::parse_int_list("", "--x").empty());
  CHECK_THROWS_AS(train::parse_int_list("20a0", "--x"), host::Error);
  s.upsample_at = {3000, 2000};
  CHECK_THROWS_AS(s.validate(), host::Error);
}

TEST_CASE("schedule: fitted to another length keeps events that fit, pulls in those that do not") {
  train::Schedule s;  // 30000 iterations, upsample 2000..5500, mask 2000, 4000
  // 8000 steps: the last event (5500) is within 80% (6400): nothing moves, only the lr horizon.
  const auto k = s.fitted(8000);
  CHECK(k.iters == 8000);
  CHECK(k.upsample_at == s.upsample_at);
  CHECK(k.mask_at == s.mask_at);
  CHECK(s.fitted(60000).upsample_at == s.upsample_at);
  // 6000 steps: 5500 > 4800, so every event is scaled by 4800 / 5500.
  const auto f = s.fitted(6000);
  CHECK(f.upsample_at == std::vector<int>{1745, 2618, 3491, 4800});
  CHECK(f.mask_at == std::vector<int>{1745, 3491});
  CHECK(f.voxel_list() == s.voxel_list());
  // 300 steps: 240 / 5500 would put the first event at 87, before 100: the factor is 100 / 2000 instead
  // and the events keep their proportions (5500 -> 275).
  const auto g = s.fitted(300);
  CHECK(g.upsample_at == std::vector<int>{100, 150, 200, 275});
  CHECK(g.mask_at == std::vector<int>{100, 200});
  // So short that events collide or land past the end: still increasing, all kept (past the end never fires).
  const auto h = s.fitted(3, 2);
  CHECK(h.upsample_at.size() == 4);
  CHECK_NOTHROW(h.validate());
  CHECK_THROWS_AS(s.fitted(0), host::Error);
}

// A clock for a loop that reads it once before and once after each step: step k (1-based) lasts step_s(k).
static train::Clock synthetic_clock(std::function<double(int)> step_s) {
  auto t = std::make_shared<double>(0.0);
  auto reads = std::make_shared<int>(0);
  return [=] {
    if ((*reads)++ % 2 == 1) *t += step_s(*reads / 2);
    return *t;
  };
}

TEST_CASE("time-budgeted run on a synthetic clock: the schedule is refitted to the budget, exactly") {
  auto cfg = small_config(100000);  // far too long for the budget: the refit must shorten it
  cfg.schedule.upsample_at = {20000};
  cfg.schedule.mask_at = {20000};
  train::DensityTrainer t(small_scene(), cfg);
  // Every program the stage launches is built before the loop; its steps (events included) build none.
  train::build_stage_programs(train::density_stage_programs(t.model()), nullptr);
  const size_t built = host::Runtime::instance().programs_built();
  std::ostringstream log;
  train::RunOptions ro;
  ro.log = &log;
  ro.time_budget_s = 4.0;
  ro.fit_schedule_to_budget = true;
  // A slow first step (1 s), then 1/64 s a step. The first refit, after step 11, measures steps 2..11:
  // 1.15625 s spent, 2.84375 s left = 182 steps, so 193 in all. Schedule::fitted(193) puts the events at
  // 0.8 x 193 / 20000 of their plan: 154.4 -> 154, inside the first 90%. Every later refit sees the same
  // rate and fits 193 again, so the schedule is refitted once.
  ro.clock = synthetic_clock([](int k) { return k == 1 ? 1.0 : 1.0 / 64; });
  std::vector<std::string> events;
  ro.after_step = [&](const train::StepStats& st) {
    for (const auto& e : st.events) events.push_back(std::to_string(st.iteration) + " " + e);
    return true;
  };
  const auto sum = train::run_density_training(t, ro);
  const auto& sch = t.config().schedule;
  INFO(log.str());
  CHECK(sum.iterations == 193);
  CHECK(sum.seconds == 4.0);  // 1 + 192 / 64
  CHECK(sch.iters == 193);
  CHECK(sch.upsample_at == std::vector<int>{154});
  CHECK(sch.mask_at == std::vector<int>{154});
  CHECK(sch.voxels_final == cfg.schedule.voxels_final);
  REQUIRE(events.size() == 2);  // the mask update and the upsample, at the refitted step
  CHECK(events[0].rfind("154 alpha mask", 0) == 0);
  CHECK(events[1].rfind("154 upsampled", 0) == 0);
  const std::string text = log.str();
  CHECK(text.find("0.02 s/it -> 193 iterations fit the budget") != std::string::npos);
  CHECK(text.find("iterations fit the budget") == text.rfind("iterations fit the budget"));
  CHECK(text.find("kernels built in ") != std::string::npos);
  CHECK(host::Runtime::instance().programs_built() == built);

  // Per-sample shading (TensoRF's) launches nothing outside the same list.
  cfg.model.deferred_shading = false;
  train::DensityTrainer per_sample(small_scene(), cfg);
  for (int i = 0; i < 3; ++i) per_sample.step(true);
  CHECK(host::Runtime::instance().programs_built() == built);
}

TEST_CASE("refit_schedule: fired events keep their steps, later ones move, never into the past or the last 10%") {
  auto cfg = small_config(200);
  cfg.schedule.upsample_at = {60, 120};
  cfg.schedule.mask_at = {60};
  train::DensityTrainer t(small_scene(), cfg);
  t.refit_schedule(100);  // fitted(100) of the 200-step plan puts the events at 100 and 200: past 90, dropped
  CHECK(t.config().schedule.iters == 100);
  CHECK(t.config().schedule.upsample_at.empty());
  CHECK(t.config().schedule.mask_at.empty());
  CHECK(t.config().schedule.voxels_final == cfg.schedule.voxels_init);  // no upsample: the grid stays
  t.refit_schedule(400);  // longer: the events come back (from the plan), scaled by 100 / 60, within 360
  CHECK(t.config().schedule.iters == 400);
  CHECK(t.config().schedule.upsample_at == std::vector<int>{100, 200});
  CHECK(t.config().schedule.mask_at == std::vector<int>{100});
  CHECK(t.config().schedule.voxels_final == cfg.schedule.voxels_final);
  for (int i = 0; i < 3; ++i) t.step();
  // After 3 steps nothing fired; a refit shorter than the steps taken runs at least one more step.
  t.refit_schedule(2);
  CHECK(t.config().schedule.iters == 4);
  CHECK(t.config().schedule.upsample_at.empty());

  // Once an event has fired it stays where it was; the later one moves with the refit, or is dropped when
  // it would land in the last 10%: the final grid is then the fired upsample's.
  auto cfg2 = small_config(400);
  cfg2.schedule.upsample_at = {150, 300};
  cfg2.schedule.mask_at = {150};
  train::DensityTrainer u(small_scene(), cfg2);
  const auto res_before = u.model().res();
  for (int i = 0; i < 151; ++i) u.step();
  CHECK(u.model().res() != res_before);  // the upsample at 150 happened
  u.refit_schedule(200);                 // fitted(200): 100, 200 -> fired 150 kept, 200 > 180 dropped
  CHECK(u.config().schedule.upsample_at == std::vector<int>{150});
  CHECK(u.config().schedule.mask_at == std::vector<int>{150});
  CHECK(u.config().schedule.voxels_after(151) == cfg2.schedule.voxels_after(151));
  CHECK(u.config().schedule.voxels_final == cfg2.schedule.voxels_after(151));
  u.refit_schedule(1000);  // room again: fitted(1000) keeps the plan's 300, inside 900: it returns
  CHECK(u.config().schedule.upsample_at == std::vector<int>{150, 300});
  CHECK(u.config().schedule.voxels_final == cfg2.schedule.voxels_final);
}

TEST_CASE("train-density smoke: loss falls and the learned depth matches the generated scene") {
  Trained& t = trained();
  // Bound: the mean batch MSE of the last 5 steps is below a quarter of the first 5 (measured ~1/30).
  CHECK(t.last_mse < t.first_mse / 4);
  for (const auto& st : t.stats) REQUIRE(std::isfinite(st.mse));
  // The schedule's events all happened: mask + box shrink and the upsample at 60.
  bool shrunk = false, upsampled = false;
  for (const auto& st : t.stats)
    for (const auto& e : st.events) shrunk |= e.find("box shrunk") != std::string::npos,
                                    upsampled |= e.find("upsampled") != std::string::npos;
  CHECK(shrunk);
  CHECK(upsampled);
  const auto& m = t.trainer->model();
  CHECK(m.geo.mask.voxels.defined());
  CHECK(m.res()[0] > 24);

  // Held-out views: PSNR and depth against the generator's ground truth.
  const auto& scene = small_scene();
  double psnr = train::mean_psnr(train::evaluate_views(m, scene, 0, false));
  double err = 0, signed_err = 0, normalised_err = 0;  // normalised: depth / acc (a ray's expected hit)
  int64_t n = 0;
  std::vector<double> errs;
  for (const auto& v : scene.test) {
    const auto r = model::render_view(m, scene, v.camera, 4096);
    std::string dpath = v.image_path;
    dpath = dpath.substr(0, dpath.size() - 4) + "_depth.exr";
    const auto gt = io::read_exr(dpath);
    REQUIRE(gt.width == r.width);
    for (size_t i = 0; i < r.acc.size(); ++i) {
      const bool fg = !v.alpha.empty() ? v.alpha[i] > 0.5f : gt.data[i] > 0;
      if (r.acc[i] > 0.5f && fg && gt.data[i] > 0) {
        err += std::abs(r.depth[i] - gt.data[i]);
        signed_err += r.depth[i] - gt.data[i];
        normalised_err += std::abs(r.depth[i] / r.acc[i] - gt.data[i]);
        errs.push_back(std::abs(r.depth[i] - gt.data[i]));
        ++n;
      }
    }
  }
  err /= std::max<int64_t>(n, 1);
  std::sort(errs.begin(), errs.end());
  const double median = errs.empty() ? 1e9 : errs[errs.size() / 2];
  std::cout << "smoke: test PSNR " << psnr << " dB, |depth error| mean " << err << " median " << median
            << " signed mean " << signed_err / std::max<int64_t>(n, 1) << ", |depth/acc error| mean "
            << normalised_err / std::max<int64_t>(n, 1) << " over " << n << " pixels" << std::endl;
  // Bounds (measured 25.0 dB, mean 0.092, median 0.082 at this size and length): 21 dB, and a mean error
  // of 0.15 world units (2 voxels of the final ~40^3 grid over the 3-unit box; the camera sits 4 units from
  // the centre, the objects span ~2.5 units).
  CHECK(psnr > 21.0);
  CHECK(n > 500);
  CHECK(err < 0.15);
  CHECK(median < 0.15);
}

TEST_CASE("backdrop term: the generated scene's transparent pixels are watched, and they stay emptier with it") {
  if (testing::small_run()) return;  // judges the trained model (see small_config)
  Trained& t = trained();
  const auto& scene = small_scene();
  REQUIRE(scene.effects.background);
  CHECK(t.trainer->config().backdrop_weight == train::kDefaultBackdropWeight);
  CHECK(t.trainer->backdrop_share() > 0.2);  // the objects cover a minority of each view
  CHECK(t.trainer->backdrop_share() < 0.95);
  int watched = 0;
  for (const auto& st : t.stats) watched += st.backdrop_rays;
  CHECK(watched > 0);
  // The same run without the term.
  auto cfg = small_config(150);
  cfg.backdrop_weight = 0;
  train::DensityTrainer off(scene, cfg);
  while (!off.done()) {
    const auto st = off.step();
    REQUIRE(st.backdrop_rays == 0);
  }
  CHECK(off.backdrop_share() == 0.0);
  const auto with = train::evaluate_views(t.trainer->model(), scene, 0, false);
  const auto without = train::evaluate_views(off.model(), scene, 0, false);
  const double a_with = train::mean_backdrop_acc(with), a_without = train::mean_backdrop_acc(without);
  std::cout << "backdrop term: held-out backdrop opacity " << a_without << " -> " << a_with << ", PSNR "
            << train::mean_psnr(without) << " -> " << train::mean_psnr(with) << " dB" << std::endl;
  REQUIRE(a_with >= 0);
  CHECK(a_with < 0.8 * a_without);
  CHECK(train::mean_psnr(with) > train::mean_psnr(without) - 0.5);
}

TEST_CASE("checkpoint: round trip keeps parameters, alpha mask, optimiser state and rendering identical") {
  Trained& t = trained();
  const std::string path = (work_dir() / "rt.ckpt").string();
  t.trainer->save(path, nlohmann::json{{"dir", "x"}});
  const auto ck = io::load_checkpoint(path, "density");
  const auto m2 = model::load_model(ck);
  const auto& m1 = t.trainer->model();
  CHECK(m2.res() == m1.res());
  CHECK(m2.geo.box_lo == m1.geo.box_lo);
  CHECK(m2.geo.step == m1.geo.step);
  CHECK(host_of(m2.geo.density.params) == host_of(m1.geo.density.params));
  CHECK(host_of(m2.rgb.app().params) == host_of(m1.rgb.app().params));
  CHECK(host_of(m2.rgb.mlp().w2) == host_of(m1.rgb.mlp().w2));
  CHECK(m2.geo.mask.to_host() == m1.geo.mask.to_host());
  CHECK(m2.geo.mask.occupied == m1.geo.mask.occupied);
  // Rendering the same rays gives bit-identical output.
  const auto& cam = small_scene().test[0].camera;
  const auto r1 = model::render_view(m1, small_scene(), cam), r2 = model::render_view(m2, small_scene(), cam);
  CHECK(r1.value == r2.value);
  CHECK(r1.depth == r2.depth);
  // A trainer restored from it carries the iteration and the optimiser state: saving it again gives the
  // same tensors.
  train::DensityTrainer resumed(small_scene(), ck);
  CHECK(resumed.iteration() == 150);
  const std::string path2 = (work_dir() / "rt2.ckpt").string();
  resumed.save(path2, nlohmann::json{{"dir", "x"}});
  const auto ck2 = io::load_checkpoint(path2, "density");
  REQUIRE(ck2.tensors.size() == ck.tensors.size());
  for (const auto& [name, tensor] : ck.tensors) CHECK_MESSAGE(ck2.get(name).data == tensor.data, name);
}

TEST_CASE("checkpoint: --resume continues from the stored iteration") {
  Trained& t = trained();
  const std::string path = (work_dir() / "resume.ckpt").string();
  t.trainer->save(path, {});
  train::DensityTrainer b(small_scene(), io::load_checkpoint(path, "density"));
  CHECK(b.iteration() == 150);
  CHECK(b.done());
  CHECK(b.model().res() == t.trainer->model().res());  // the upsample at 60 is in the checkpoint
  b.set_total_iters(155);
  const auto st = b.step();
  CHECK(st.iteration == 151);
  // It continues from the trained state, not from scratch: within 2x of the last MSE, far below the first.
  CHECK(st.mse < 2 * t.last_mse);
  CHECK(st.mse < t.first_mse / 4);
  int steps = 1;
  while (!b.done()) b.step(), ++steps;
  CHECK(steps == 5);
}

TEST_CASE("checkpoint: missing, corrupt, truncated, foreign and wrong-kind files give errors naming the file") {
  Trained& t = trained();
  const std::string good = (work_dir() / "good.ckpt").string();
  t.trainer->save(good, {});
  auto expect_error = [](const std::string& path, const std::string& kind, const std::string& words) {
    try {
      io::load_checkpoint(path, kind);
      FAIL("no error for " << path);
    } catch (const host::Error& e) {
      const std::string msg = e.what();
      CHECK_MESSAGE(msg.find(path) != std::string::npos, msg);
      CHECK_MESSAGE(msg.find(words) != std::string::npos, msg);
    }
  };
  expect_error((work_dir() / "nope.ckpt").string(), "density", "does not exist");
  expect_error(good, "feature", "expected 'feature'");

  const std::string flipped = (work_dir() / "flipped.ckpt").string();
  fs::copy_file(good, flipped, fs::copy_options::overwrite_existing);
  flip_byte(flipped, 100);  // inside the tensor data
  expect_error(flipped, "density", "corrupt");

  const std::string cut = (work_dir() / "cut.ckpt").string();
  fs::copy_file(good, cut, fs::copy_options::overwrite_existing);
  fs::resize_file(cut, fs::file_size(good) / 2);
  expect_error(cut, "density", "not a readable stylerf checkpoint");

  const std::string text = (work_dir() / "text.ckpt").string();
  std::ofstream(text) << "hello, not a checkpoint";
  expect_error(text, "density", "not a readable stylerf checkpoint");

  const std::string foreign = (work_dir() / "foreign.safetensors").string();
  io::save_safetensors(foreign, {{"w", io::HostTensor{{2}, {1.0f, 2.0f}}}});
  expect_error(foreign, "density", "not a stylerf checkpoint");

  const std::string future = (work_dir() / "future.ckpt").string();
  io::save_safetensors(future, {{"w", io::HostTensor{{1}, {1.0f}}}},
                       {{"stylerf.format", "stylerf-checkpoint"}, {"stylerf.version", "99"}});
  expect_error(future, "density", "version '99'");
}

TEST_CASE("checkpoint: a failed save leaves the previous file intact and no temporary behind") {
  const fs::path dir = work_dir() / "atomic";
  fs::create_directories(dir);
  const std::string path = (dir / "model.ckpt").string();
  io::Checkpoint ck;
  ck.kind = "density";
  ck.tensors["a"] = io::HostTensor{{3}, {1, 2, 3}};
  io::save_checkpoint(path, ck);
  const auto before = files_in(dir);
  io::Checkpoint bad = ck;
  bad.tensors["b"] = io::HostTensor{{4}, {1, 2}};  // shape says 4 values, 2 given: the writer refuses
  CHECK_THROWS_AS(io::save_checkpoint(path, bad), host::Error);
  CHECK(files_in(dir) == before);
  CHECK(io::load_checkpoint(path, "density").get("a").data == std::vector<float>{1, 2, 3});
  // Writing over a directory fails at the rename; the temporary is removed.
  fs::create_directories(dir / "sub.ckpt");
  CHECK_THROWS(io::save_checkpoint((dir / "sub.ckpt").string(), ck));
  CHECK(files_in(dir) == std::vector<std::string>{"model.ckpt", "sub.ckpt"});
}

TEST_CASE("train-density: a non-finite loss stops with an error naming the iteration") {
  train::DensityTrainer tr(small_scene(), small_config(10));
  tr.step();
  tr.step();
  // A NaN background colour makes every ray's colour NaN (compositing and the head's sigmoid would swallow
  // NaN density or NaN logits; the background is added as it is).
  tr.model().geo.background = {std::nanf(""), 0.5f, 0.5f};
  try {
    tr.step();
    FAIL("no error for a NaN loss");
  } catch (const host::Error& e) {
    const std::string msg = e.what();
    CHECK_MESSAGE(msg.find("iteration 3") != std::string::npos, msg);
  }
}

TEST_CASE("train-density: a NaN in the grid (invisible in the loss) is caught and never checkpointed") {
  auto cfg = small_config(10);
  cfg.finite_check_every = 2;
  train::DensityTrainer tr(small_scene(), cfg);
  tr.step();
  // One NaN density coefficient: the compositing treats its samples as empty, so the loss stays finite.
  auto& grid = tr.model().geo.density.params;
  std::vector<float> values = grid.to_host();
  values[values.size() / 2] = std::nanf("");
  grid.upload(values);
  const std::string path = (work_dir() / "nan.ckpt").string();
  fs::remove(path);
  CHECK_THROWS_WITH_AS(tr.save(path, {}), doctest::Contains("checkpoint"), host::Error);
  CHECK_FALSE(fs::exists(path));
  try {
    tr.step();  // iteration 2: checked
    FAIL("no error for a NaN grid");
  } catch (const host::Error& e) {
    const std::string msg = e.what();
    CHECK_MESSAGE(msg.find("parameter 'density'") != std::string::npos, msg);
    CHECK_MESSAGE(msg.find("after iteration 2") != std::string::npos, msg);
  }
}
