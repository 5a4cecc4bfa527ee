#include "tests/small_scene.hpp"

#include <cstdlib>
#include <string>
#include <system_error>
#include <unistd.h>

#include "lib/io/checkpoint.hpp"
#include "lib/model/style_model.hpp"
#include "lib/scene/make_scene.hpp"
#include "lib/scene/scene_meta.hpp"
#include "lib/train/density_trainer.hpp"
#include "tests/testing.hpp"

namespace stylerf::testing {

namespace fs = std::filesystem;

// Removed when the test process exits (each run writes a few hundred MB of scenes and checkpoints that
// would pile up in the temporary folder); STYLERF_KEEP_TEST_DIRS=1 keeps it for a look after a failure.
struct WorkDir {
  fs::path path;
  ~WorkDir() {
    const char* keep = std::getenv("STYLERF_KEEP_TEST_DIRS");
    std::error_code ec;
    if (!(keep && std::string(keep) == "1")) fs::remove_all(path, ec);
  }
};

fs::path small_work_dir() {
  static WorkDir dir{[] {
    fs::path d = fs::temp_directory_path() / ("stylerf_test_small_" + std::to_string(::getpid()));
    fs::remove_all(d);
    fs::create_directories(d);
    return d;
  }()};
  return dir.path;
}

const scene::Scene& small_scene() {
  static scene::Scene s = [] {
    scene::MakeSceneOptions mo;
    mo.size = 48;
    mo.views = 20;
    const std::string dir = (small_work_dir() / "scene").string();
    scene::make_scene(dir, mo);
    return scene::load_scene(dir);
  }();
  return s;
}

const model::Geometry& small_geometry() {
  static model::Geometry g = [] {
    auto cfg = train::default_density_config(small_scene());
    cfg.model.density_rank = {8, 8, 8};
    cfg.model.app_rank = {8, 8, 8};
    cfg.model.hidden = 32;
    cfg.model.act = field::DensityActivation::Relu;
    cfg.schedule.iters = 80;
    cfg.schedule.voxels_init = 24 * 24 * 24;
    cfg.schedule.voxels_final = 32 * 32 * 32;
    cfg.schedule.upsample_at = {50};
    cfg.schedule.mask_at = {50};
    cfg.batch = 1024;
    if (small_run()) {  // the same schedule (upsample and mask included) at a sixteenth of the work
      cfg.schedule.iters = 20;
      cfg.schedule.upsample_at = {12};
      cfg.schedule.mask_at = {12};
      cfg.batch = 256;
    }
    train::DensityTrainer t(small_scene(), cfg);
    while (!t.done()) t.step();
    return t.model().geo;
  }();
  return g;
}

const SmallStageFiles& small_stage_files() {
  static SmallStageFiles files = [] {
    const scene::Scene& sc = small_scene();
    model::FeatureFieldConfig fc;
    fc.rank = {8, 8, 8};
    model::FeatureModel f = model::FeatureModel::create(small_geometry(), fc, model::DecoderProfile::Fast, 3);
    const nlohmann::json meta = scene::scene_meta(sc.root, scene::LoadOptions{}, sc);
    SmallStageFiles out{(small_work_dir() / "cli_features.ckpt").string(), (small_work_dir() / "cli_style.ckpt").string()};
    {
      io::Checkpoint ck;
      ck.kind = "features";
      f.save(ck);
      ck.meta["scene"] = meta;
      io::save_checkpoint(out.features, ck);
    }
    model::StyleModel m = model::StyleModel::create(std::move(f), style::SictMode::VolumeAdaptive, true, 5);
    m.sict.running_var.value = host::Tensor::full({256}, 0.05f);
    io::Checkpoint ck;
    ck.kind = "style";
    m.save(ck);
    ck.meta["scene"] = meta;
    io::save_checkpoint(out.style, ck);
    return out;
  }();
  return files;
}

}  // namespace stylerf::testing
