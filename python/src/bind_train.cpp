// The three stages' trainers: the library's loops (lib/train) with the stage's default configuration, as
// the CLI builds it, a length in iterations or minutes, and a progress callback. Each writes the same
// checkpoint as `stylerf train-density / train-features / train-style` with the same settings, and takes
// its inputs alike: checkpoints and folders as paths (str or os.PathLike), the scene as a Scene or its
// folder (the later stages' default: the one their input checkpoint records), the CLI's option names.
//
// The callback gets a dict after every step, with the GIL held; returning False stops training early (the
// checkpoint is then written as at the end of a run). An exception raised in it propagates out of the
// loop before the final checkpoint is written; a periodic checkpoint written earlier is whole (written
// atomically), and no partial file is left at `out`.
#include <filesystem>

#include "host/error.hpp"
#include "lib/io/checkpoint.hpp"
#include "lib/model/density_model.hpp"
#include "lib/scene/scene_meta.hpp"
#include "lib/train/density_trainer.hpp"
#include "lib/train/feature_trainer.hpp"
#include "lib/train/recipes.hpp"
#include "lib/train/style_trainer.hpp"
#include "python/src/handles.hpp"
#include "python/src/path_args.hpp"

namespace stylerf::py {

namespace {

namespace fs = std::filesystem;

struct Length {
  int iters = 0;       // 0: by time
  double seconds = 0;  // 0: by iterations
};

Length check_length(std::optional<int> iters, std::optional<double> minutes) {
  if (iters.has_value() == minutes.has_value()) throw pyb::value_error("give exactly one of iters= and minutes=");
  if (iters && (*iters < 1 || *iters > 10000000)) throw pyb::value_error("iters: must be in [1, 10000000]");
  if (minutes && !(*minutes > 0 && std::isfinite(*minutes) && *minutes <= 100000))
    throw pyb::value_error("minutes: must be a positive number of minutes");
  return {iters.value_or(0), minutes.value_or(0) * 60.0};
}

// The checkpoint path to write, its folder created; FileExistsError when it exists and force is off.
std::string check_output(const fs::path& out_arg, bool force, int checkpoint_every) {
  const std::string out = path_arg(out_arg, "out");
  if (checkpoint_every < 0) throw pyb::value_error("checkpoint_every: must be >= 0 (0: only at the end)");
  std::error_code ec;
  if (fs::is_directory(out, ec)) throw pyb::value_error("out: " + out + " is a folder; give a checkpoint file name");
  if (fs::exists(out, ec) && !force) {
    PyErr_SetString(PyExc_FileExistsError, (out + " exists; pass force=True to replace it").c_str());
    throw pyb::error_already_set();
  }
  const fs::path dir = fs::path(out).has_parent_path() ? fs::path(out).parent_path() : fs::path(".");
  fs::create_directories(dir, ec);
  if (ec) throw pyb::value_error("out: cannot create the folder " + dir.string() + " (" + ec.message() + ")");
  return out;
}

// A recipe or profile name (fast | paper), or a ValueError naming the argument, the value and the choices.
void check_choice(const std::string& value, const char* arg) {
  if (value != "fast" && value != "paper")
    throw pyb::value_error(std::string(arg) + ": '" + value + "' is not one of: fast, paper");
}

// A loss a step measured, or None for the one its kind of step does not (a feature step's two losses).
pyb::object or_none(bool measured, double value) { return measured ? pyb::object(pyb::float_(value)) : pyb::none(); }

// Calls `cb` (None: nothing) with the GIL held; false only when it returned False.
bool report(const pyb::object& cb, const std::function<pyb::dict()>& make) {
  if (cb.is_none()) return true;
  pyb::gil_scoped_acquire gil;
  const pyb::object r = cb(make());
  return !(pyb::isinstance<pyb::bool_>(r) && !r.cast<bool>());
}

std::string train_density(const SceneArg& scene_arg, const fs::path& out_arg, std::optional<int> iters,
                          std::optional<double> minutes, const pyb::object& progress, uint64_t seed, int batch,
                          int checkpoint_every, bool force) {
  const Length len = check_length(iters, minutes);
  if (batch < 1 || batch > (1 << 22)) throw pyb::value_error("batch: must be in [1, 4194304]");
  const std::string out = check_output(out_arg, force, checkpoint_every);
  const std::shared_ptr<SceneHandle> handle = scene_of(scene_arg, "scene");
  const SceneHandle& sc = *handle;
  LibraryCall call;
  auto cfg = train::default_density_config(sc.scene);
  if (len.iters > 0) cfg.schedule = cfg.schedule.fitted(len.iters);  // as `train-density --iters`
  cfg.batch = batch;
  cfg.seed = seed;
  train::DensityTrainer trainer(sc.scene, cfg);
  train::RunOptions ro;
  ro.checkpoint = out;
  ro.checkpoint_every = checkpoint_every;
  ro.time_budget_s = len.seconds;
  ro.fit_schedule_to_budget = len.seconds > 0;
  ro.scene_meta = scene::scene_meta(sc.dir, sc.options, sc.scene);
  ro.after_step = [&](const train::StepStats& st) {
    return report(progress, [&] {
      return pyb::dict(pyb::arg("stage") = "density", pyb::arg("iteration") = st.iteration,
                       pyb::arg("total") = trainer.config().schedule.iters, pyb::arg("mse") = st.mse,
                       pyb::arg("psnr") = st.psnr, pyb::arg("seconds") = st.seconds);
    });
  };
  train::run_density_training(trainer, ro);
  return out;
}

std::string train_features(const fs::path& density_arg, const fs::path& out_arg, const std::optional<SceneArg>& scene_arg,
                           std::optional<int> iters, std::optional<double> minutes, const pyb::object& progress,
                           const std::string& profile, uint64_t seed, int checkpoint_every, bool force) {
  const Length len = check_length(iters, minutes);
  check_choice(profile, "profile");
  const model::DecoderProfile prof = model::parse_decoder_profile(profile);
  const std::string density = path_arg(density_arg, "density");
  const std::string out = check_output(out_arg, force, checkpoint_every);
  const scene::SceneOverrides overrides = scene_overrides(scene_arg, "scene");
  LibraryCall call;
  const io::Checkpoint dck = io::load_checkpoint(density, "density");
  const model::Geometry geo = model::load_model(dck).geo;
  const auto opened = scene::open_scene_for(dck.meta.value("scene", nlohmann::json::object()), density, overrides);
  auto cfg = train::default_feature_config(opened.scene, prof);
  if (len.iters > 0) cfg.iters = len.iters;
  cfg.seed = seed;
  train::FeatureTrainer trainer(opened.scene, geo, cfg, nullptr);
  if (len.seconds > 0) trainer.set_total_iters(1000000);  // refitted from the measured rate, as the CLI
  train::FeatureRunOptions ro;
  ro.checkpoint = out;
  ro.checkpoint_every = checkpoint_every;
  ro.time_budget_s = len.seconds;
  ro.scene_meta = scene::scene_meta(opened.dir, opened.options, opened.scene);
  ro.density_meta = train::density_source_meta(density, dck);
  ro.after_step = [&](const train::FeatureStepStats& st) {
    return report(progress, [&] {
      return pyb::dict(pyb::arg("stage") = "features", pyb::arg("iteration") = st.iteration,
                       pyb::arg("total") = trainer.config().iters, pyb::arg("patch") = st.patch,
                       pyb::arg("feature_mse") = or_none(!st.patch, st.feature_mse),
                       pyb::arg("pixel_mse") = or_none(st.patch, st.pixel_mse),
                       pyb::arg("seconds") = st.seconds);
    });
  };
  train::run_feature_training(trainer, ro);
  return out;
}

std::string train_style(const fs::path& features_arg, const fs::path& styles_arg, const fs::path& out_arg,
                        const std::optional<SceneArg>& scene_arg, std::optional<int> iters,
                        std::optional<double> minutes, const pyb::object& progress, int holdout_styles,
                        const std::optional<std::string>& recipe, uint64_t seed, int checkpoint_every, bool force) {
  const Length len = check_length(iters, minutes);
  if (holdout_styles < 0) throw pyb::value_error("holdout_styles: must be >= 0");
  if (recipe) check_choice(*recipe, "recipe");
  const std::string features = path_arg(features_arg, "features"), styles = path_arg(styles_arg, "styles");
  const std::string out = check_output(out_arg, force, checkpoint_every);
  const scene::SceneOverrides overrides = scene_overrides(scene_arg, "scene");
  LibraryCall call;
  const io::Checkpoint ck = io::load_checkpoint(features, "features");
  const nlohmann::json recorded = ck.meta.value("scene", nlohmann::json::object());
  const auto opened = scene::open_scene_for(recorded, features, overrides);
  const scene::Scene& sc = opened.scene;
  // A scene named here is recorded as loaded; otherwise the record passes on unchanged, as the CLI's.
  const nlohmann::json scene_meta =
      scene_arg ? scene::scene_meta(opened.dir, opened.options, opened.scene) : recorded;
  model::FeatureModel fm = model::FeatureModel::load(ck);
  train::StyleTrainConfig cfg = train::style_recipe(train::style_recipe_for(fm, recipe.value_or(""), features));
  if (len.iters > 0) cfg.iters = len.iters;
  cfg.seed = seed;
  auto set = train::StyleSet::from_dir(styles, holdout_styles, nullptr);
  train::StyleTrainer trainer(sc, std::move(fm), std::move(set), cfg, nullptr);
  if (len.seconds > 0) trainer.set_total_iters(1000000);  // refitted from the measured rate, as the CLI
  train::StyleRunOptions ro;
  ro.eval_every = 0;  // held-out losses are only printed: no log here
  ro.checkpoint = out;
  ro.checkpoint_every = checkpoint_every;
  ro.time_budget_s = len.seconds;
  ro.scene_meta = scene_meta;
  ro.after_step = [&](const train::StyleStepStats& st) {
    return report(progress, [&] {
      return pyb::dict(pyb::arg("stage") = "style", pyb::arg("iteration") = st.iteration,
                       pyb::arg("total") = trainer.config().iters, pyb::arg("warm") = st.warm,
                       pyb::arg("content") = st.content, pyb::arg("style") = st.style,
                       pyb::arg("seconds") = st.seconds);
    });
  };
  train::run_style_training(trainer, ro);
  return out;
}

}  // namespace

void bind_train(pyb::module_& m) {
  using pyb::arg;
  const auto none = pyb::none();
  m.def("train_density", &train_density, arg("scene"), arg("out"), pyb::kw_only(), arg("iters") = none,
        arg("minutes") = none, arg("progress") = none, arg("seed") = 0, arg("batch") = 4096,
        arg("checkpoint_every") = 1000, arg("force") = false,
        "Stage 1 (`stylerf train-density`): TensoRF's VM grids on the scene's images (a Scene or its folder). "
        "Give exactly one of iters and minutes. progress gets a dict after every step (returning False stops "
        "early). Writes the checkpoint out (force: replace an existing one) and returns its path.");
  m.def("train_features", &train_features, arg("density"), arg("out"), pyb::kw_only(), arg("scene") = none,
        arg("iters") = none, arg("minutes") = none, arg("progress") = none, arg("profile") = "fast",
        arg("seed") = 0, arg("checkpoint_every") = 500, arg("force") = false,
        "Stage 2 (`stylerf train-features`): the feature field and its decoder over a density checkpoint's frozen "
        "geometry. scene: a Scene or folder when the scene moved (None: the checkpoint's). profile: fast (features "
        "at 1/4 resolution) or paper. Lengths, progress, out and force as train_density's.");
  m.def("train_style", &train_style, arg("features"), arg("styles"), arg("out"), pyb::kw_only(), arg("scene") = none,
        arg("iters") = none, arg("minutes") = none, arg("progress") = none, arg("holdout_styles") = 12,
        arg("recipe") = none, arg("seed") = 0, arg("checkpoint_every") = 200, arg("force") = false,
        "Stage 3 (`stylerf train-style`): SICT and DST over a feature checkpoint, trained on a folder of style "
        "images, holdout_styles of them held out. recipe: fast or paper (None: the one named like the feature "
        "checkpoint's profile). scene, lengths, progress, out and force as train_features'.");
}

}  // namespace stylerf::py
