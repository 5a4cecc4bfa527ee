// What the Python objects hold. A StyleModel opens its checkpoint, the scene it was trained on (cameras
// only), VGG, the style encoder and the scene's style statistics once; its StyleCodes keep it alive, since
// a code is that model's (DST's style branch) and is re-normalised with that scene's statistics.
#pragma once
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <memory>
#include <mutex>
#include <string>
#include <variant>

#include "lib/model/scene_style_stats.hpp"
#include "lib/model/style_model.hpp"
#include "lib/nn/vgg.hpp"
#include "lib/scene/scene.hpp"
#include "lib/style/style_encoder.hpp"

namespace stylerf::py {

namespace pyb = pybind11;

// Every call into the library holds one of these: the GIL is released first, so other Python threads run
// meanwhile, then a process-wide lock is taken, since the library is not thread-safe (one OpenCL runtime,
// one queue, one buffer pool). The lock is recursive: a progress callback (which takes the GIL back) may
// call into the library again between training steps.
class LibraryCall {
 public:
  LibraryCall() : lock_(mutex()) {}

 private:
  static std::recursive_mutex& mutex() {
    static std::recursive_mutex m;
    return m;
  }
  pyb::gil_scoped_release release_;  // declared first: released before the lock is taken, retaken after
  std::unique_lock<std::recursive_mutex> lock_;
};

// A scene as loaded, with what scene_meta needs to record it in a checkpoint.
struct SceneHandle {
  scene::Scene scene;
  std::string dir;
  scene::LoadOptions options;
};

struct ModelState {
  std::string path;
  model::StyleModel model;
  scene::Scene scene;
  nn::VggEncoder vgg;
  std::unique_ptr<style::StyleEncoder> encoder;  // refers to model.dst and vgg
  std::unique_ptr<model::SceneStyleStats> stats;  // refers to model
};
using ModelHandle = std::shared_ptr<ModelState>;

struct CodeHandle {
  style::StyleCode code;  // scene statistics attached
  ModelHandle owner;
  std::string source;     // the image path, "<array>" or "mix"
};

// A view index (into the scene's held-out views; its training views when it has none) or a camera.
using ViewOrCamera = std::variant<int, scene::Camera>;
scene::Camera resolve_view(const scene::Scene& scene, const ViewOrCamera& v);

// A supersample argument: n (n x n rays a block, 1..8), "quincunx", or None for the model's recipe's.
using SupersampleArg = std::optional<std::variant<int, std::string>>;
// Its value (model::kQuincunx for the quincunx); a ValueError "supersample: ..." when it is none of those.
int supersample_of(const ModelState& s, const SupersampleArg& arg);

void bind_runtime(pyb::module_& m);
void bind_scene(pyb::module_& m);
void bind_model(pyb::module_& m);
void bind_train(pyb::module_& m);
void bind_eval(pyb::module_& m);
void bind_image(pyb::module_& m);

}  // namespace stylerf::py
