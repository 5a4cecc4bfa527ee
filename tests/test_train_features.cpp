// The feature stage end to end on a generated scene: a short density stage, then feature training (both
// losses fall, both profiles run, patch steps reach the decoder and the grid), checkpoints (round trip
// renders identically, resume continues), and bad inputs (another scene's density checkpoint, missing
// decoder weights, a decoder architecture this build does not have), plus an all-background patch and the pixels-only
// patch loss (content weight 0).
#include <doctest/doctest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <unistd.h>

#include "host/error.hpp"
#include "host/runtime.hpp"
#include "lib/nn/decoder.hpp"
#include "lib/nn/layout.hpp"
#include "lib/nn/ops.hpp"
#include "lib/scene/make_scene.hpp"
#include "lib/scene/scene_meta.hpp"
#include "lib/train/density_trainer.hpp"
#include "lib/train/feature_trainer.hpp"
#include "lib/train/reconstruction_loss.hpp"
#include "lib/train/stage_programs.hpp"
#include "tests/small_scene.hpp"
#include "tests/testing.hpp"

using namespace stylerf;
namespace fs = std::filesystem;

namespace {

fs::path work_dir() { return testing::small_work_dir(); }
using testing::small_scene;
const model::Geometry& geometry() { return testing::small_geometry(); }

train::FeatureTrainConfig small_config(model::DecoderProfile profile, int iters) {
  auto cfg = train::default_feature_config(small_scene(), profile);
  cfg.field.rank = {8, 8, 8};
  cfg.iters = iters;
  cfg.batch = 1024;
  cfg.patch = 48;
  cfg.seed = 2;
  return cfg;
}

}  // namespace

TEST_CASE("feature stage (fast profile): ray and patch losses fall; checkpoint round trip; resume") {
  train::FeatureTrainer t(small_scene(), geometry(), small_config(model::DecoderProfile::Fast, 120), nullptr);
  // Every program the stage launches is built before its loop's clock starts: its steps build none.
  train::build_stage_programs(train::feature_stage_programs(t.model()), nullptr);
  const size_t built = host::Runtime::instance().programs_built();
  const double v0 = t.view_feature_mse(0);
  std::vector<train::FeatureStepStats> st;
  while (!t.done()) st.push_back(t.step());
  CHECK(host::Runtime::instance().programs_built() == built);
  const double v1 = t.view_feature_mse(0);
  auto mean_of = [&](bool patch, bool first) {
    double s = 0;
    int n = 0;
    for (size_t i = 0; i < st.size() && n < 5; ++i) {
      const auto& x = st[first ? i : st.size() - 1 - i];
      if (x.patch != patch) continue;
      s += patch ? x.pixel_mse : x.feature_mse;
      ++n;
    }
    return s / n;
  };
  const double p0 = mean_of(true, true), p1 = mean_of(true, false);
  std::cout << "feature mse of training view 0 " << v0 << " -> " << v1 << " (batches " << mean_of(false, true)
            << " -> " << mean_of(false, false) << "), patch mse " << p0 << " -> " << p1 << std::endl;
  for (const auto& x : st) REQUIRE(std::isfinite(x.patch ? x.pixel_mse : x.feature_mse));
  // Bounds (measured over 120 steps at this size, pixels-only patch loss: view feature mse 15.3 -> 13.0,
  // patch mse 0.17 -> 0.023; 15.3 -> 14.0 and 0.28 -> 0.042 with the paper's VGG term).
  CHECK(v1 < v0 * 0.95);
  CHECK(p1 < p0 * 0.5);

  const std::string path = (work_dir() / "features.ckpt").string();
  t.save(path, {{"name", small_scene().name}}, {{"path", "x"}});
  const auto ck = io::load_checkpoint(path, "features");
  const auto m2 = model::FeatureModel::load(ck);
  const auto& cam = small_scene().test[0].camera;
  const auto a = t.model().render_decoded(small_scene(), cam), b = m2.render_decoded(small_scene(), cam);
  CHECK(a.rgb == b.rgb);
  CHECK(a.width == 48);
  CHECK(a.map.width == 12);
  CHECK(testing::all_finite(a.rgb));
  // Resume: the iteration and optimiser state carry over and training continues.
  train::FeatureTrainer r(small_scene(), ck, nullptr);
  CHECK(r.iteration() == 120);
  r.set_total_iters(122);
  r.step();
  r.step();
  CHECK(r.done());
  const auto scores = train::evaluate_decoded(r.model(), small_scene(), 2, true);
  CHECK(scores.size() == 2);
  for (const auto& s : scores) CHECK(std::isfinite(s.psnr));
}

TEST_CASE("feature stage (paper profile): full-resolution features through the PlainDecoder train") {
  auto cfg = small_config(model::DecoderProfile::Paper, 6);
  cfg.patch = 32;
  train::FeatureTrainer t(small_scene(), geometry(), cfg, nullptr);
  CHECK(t.model().stride() == 1);
  CHECK(t.model().decoder.spec().same_architecture(nn::plain_decoder_spec()));
  train::build_stage_programs(train::feature_stage_programs(t.model()), nullptr);
  const size_t built = host::Runtime::instance().programs_built();
  std::vector<double> patch;
  while (!t.done()) {
    auto s = t.step();
    if (s.patch) patch.push_back(s.pixel_mse);
    CHECK(std::isfinite(s.patch ? s.pixel_mse : s.feature_mse));
  }
  CHECK(host::Runtime::instance().programs_built() == built);  // the PlainDecoder too launches only listed programs
  CHECK(patch.size() == 3);
  // The decoder and grid both receive the patch gradient: the rendered view changed from a fresh model.
  const auto& cam = small_scene().test[0].camera;
  const auto fresh = model::FeatureModel::create(geometry(), cfg.field, cfg.profile, cfg.seed);
  CHECK(fresh.render_decoded(small_scene(), cam).rgb != t.model().render_decoded(small_scene(), cam).rgb);
}

TEST_CASE("feature stage: an all-background patch (every ray misses) gives a finite loss and no grid gradient") {
  auto m = model::FeatureModel::create(geometry(), small_config(model::DecoderProfile::Fast, 1).field,
                                       model::DecoderProfile::Fast, 1);
  const int h = 4, w = 4;
  std::vector<float> o, d;
  for (int i = 0; i < h * w; ++i) o.insert(o.end(), {10.0f, 10.0f, 10.0f + i}), d.insert(d.end(), {0.0f, 0.0f, 1.0f});
  model::FeatureField::Context ctx;
  auto r = m.field.render(m.geo, host::Tensor::from_host(o, {h * w, 3}), host::Tensor::from_host(d, {h * w, 3}), {},
                          &ctx);
  CHECK(r.acc.to_host() == std::vector<float>(h * w, 0.0f));
  nn::ConvStack::Ctx dc;
  host::Tensor rgb = m.decoder.forward(nn::rows_to_image(r.value, h, w), &dc);
  CHECK(testing::all_finite(rgb.to_host()));
  m.zero_grad();
  host::Tensor dmap = m.decoder.backward(dc, host::Tensor::full(rgb.shape(), 1e-3f), true);
  m.field.render_backward(m.geo, ctx, nn::rows_to_image_backward(dmap), host::Tensor());
  CHECK(m.field.head.grid_param().grad.to_host() ==
        std::vector<float>(m.field.head.grid_param().value.numel(), 0.0f));
  CHECK(testing::all_finite(m.field.basis.grad.to_host()));
}

TEST_CASE("feature stage: bad inputs give clear errors") {
  // A density checkpoint of another scene (or another downsample).
  const nlohmann::json other{{"name", "fern"}, {"format", "llff-forward"}, {"downsample", 8}};
  testing::expect_error([&] { scene::check_same_scene(other, small_scene(), 1, "other.ckpt"); },
                        "checkpoint other.ckpt was trained on scene 'fern'");
  nlohmann::json same{{"name", small_scene().name}, {"format", small_scene().format}, {"downsample", 1}};
  CHECK(testing::error_of([&] { scene::check_same_scene(same, small_scene(), 1, "x"); }).empty());
  testing::expect_error([&] { scene::check_same_scene(same, small_scene(), 2, "x"); }, "downsample 1");

  // Missing decoder weights (the fast profile starts from AdaIN's decoder): the error names the file.
  {
    const char* prev = std::getenv("STYLERF_WEIGHTS");
    const std::string keep = prev ? prev : "";
    const auto empty = work_dir() / "no_weights";
    fs::create_directories(empty);
    ::setenv("STYLERF_WEIGHTS", empty.c_str(), 1);
    const std::string msg = testing::error_of([&] {
      model::FeatureModel::create(geometry(), {}, model::DecoderProfile::Fast, 0);
    });
    if (prev) ::setenv("STYLERF_WEIGHTS", keep.c_str(), 1); else ::unsetenv("STYLERF_WEIGHTS");
    CHECK_MESSAGE(msg.find("adain_decoder") != std::string::npos, msg);
  }

  // A checkpoint whose decoder is not this build's decoder of its profile.
  train::FeatureTrainer t(small_scene(), geometry(), small_config(model::DecoderProfile::Fast, 1), nullptr);
  io::Checkpoint ck;
  ck.kind = "features";
  t.model().save(ck);
  ck.meta["feature_model"]["decoder"] = "reflect 256-3";
  testing::expect_error([&] { model::FeatureModel::load(ck); }, "its decoder is 'reflect 256-3'");
  ck.meta["feature_model"]["profile"] = "huge";
  testing::expect_error([&] { model::FeatureModel::load(ck); }, "unknown decoder profile 'huge'");
  // A density checkpoint where a feature checkpoint is expected.
  const std::string dpath = (work_dir() / "d.ckpt").string();
  io::Checkpoint dck;
  dck.kind = "density";
  io::save_checkpoint(dpath, dck);
  testing::expect_error([&] { io::load_checkpoint(dpath, "features"); }, "expected 'features'");
}

TEST_CASE("feature stage: constant features (a flat map) decode, and the patch losses and gradients stay finite") {
  auto m = model::FeatureModel::create(geometry(), small_config(model::DecoderProfile::Fast, 1).field,
                                       model::DecoderProfile::Fast, 1);
  nn::VggEncoder vgg = nn::VggEncoder::load_default();
  for (float value : {0.0f, 2.0f, 1e3f}) {
    CAPTURE(value);
    const host::Tensor map = host::Tensor::full({1, 256, 12, 12}, value);
    nn::ConvStack::Ctx dc;
    const host::Tensor rgb = m.decoder.forward(map, &dc);
    REQUIRE(rgb.shape() == host::Shape{1, 3, 48, 48});
    CHECK(testing::all_finite(rgb.to_host()));
    const host::Tensor gt = host::Tensor::full({1, 3, 48, 48}, 0.5f);  // flat target too: zero variance
    const auto ft = vgg.forward(gt, 4, false);
    const auto fo = vgg.forward(rgb, 4, true);
    nn::VggFeatures g;
    g[2] = nn::mse_backward(fo[2], ft[2], 0.1f);
    g[3] = nn::mse_backward(fo[3], ft[3], 0.1f);
    host::Tensor drgb = vgg.backward(g);
    vgg.release();
    m.zero_grad();
    const host::Tensor dmap = m.decoder.backward(dc, drgb, true);
    CHECK(testing::all_finite(dmap.to_host()));
    CHECK(m.first_nonfinite().empty());
    for (nn::Param* p : m.decoder.params()) CHECK(testing::all_finite(p->grad.to_host()));
  }
}

TEST_CASE("feature stage: content weight 0 is the pixel MSE alone, with its exact gradient and no VGG taps") {
  nn::VggEncoder vgg = nn::VggEncoder::load_default();
  std::vector<float> a(3 * 16 * 16), b(a.size());
  for (size_t i = 0; i < a.size(); ++i) {
    a[i] = float((i * 37) % 101) / 100.0f;
    b[i] = float((i * 53) % 89) / 88.0f;
  }
  const host::Tensor rgb = host::Tensor::from_host(a, {1, 3, 16, 16}), gt = host::Tensor::from_host(b, {1, 3, 16, 16});
  // The targets' taps are not read at weight 0: an empty set is accepted.
  const train::ReconstructionLoss l0 = train::reconstruction_loss(vgg, rgb, gt, nn::VggFeatures{}, 0.0f);
  double se = 0;
  for (size_t i = 0; i < a.size(); ++i) se += (double(a[i]) - b[i]) * (double(a[i]) - b[i]);
  CHECK(l0.pixel_mse == doctest::Approx(se / double(a.size())).epsilon(1e-5));
  CHECK(l0.feature_mse == 0.0);
  const auto g = l0.drgb.to_host();
  REQUIRE(g.size() == a.size());
  for (size_t i = 0; i < a.size(); ++i)
    CHECK(g[i] == doctest::Approx(2.0 * (double(a[i]) - b[i]) / double(a.size())).epsilon(1e-5));
  // A positive weight adds the VGG terms: the same pixel MSE, a feature MSE, a different gradient.
  const train::ReconstructionLoss l1 = train::reconstruction_loss(vgg, rgb, gt, vgg.forward(gt, 4, false), 0.1f);
  CHECK(l1.pixel_mse == doctest::Approx(l0.pixel_mse).epsilon(1e-6));
  CHECK(l1.feature_mse > 0.0);
  CHECK(l1.drgb.to_host() != g);
  // The trainer accepts 0 and refuses a negative or non-finite weight, naming the setting.
  auto cfg = small_config(model::DecoderProfile::Fast, 4);
  cfg.content_weight = 0.0f;
  train::FeatureTrainer t(small_scene(), geometry(), cfg, nullptr);
  while (!t.done()) {
    const auto s = t.step();
    CHECK(std::isfinite(s.patch ? s.pixel_mse : s.feature_mse));
    if (s.patch) CHECK(s.content == 0.0);
  }
  cfg.content_weight = -0.1f;
  testing::expect_error([&] { cfg.validate(); }, "content_weight");
  cfg.content_weight = std::nanf("");
  testing::expect_error([&] { cfg.validate(); }, "content_weight");
}
