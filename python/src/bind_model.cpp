// StyleModel (a style checkpoint, zero-shot), StyleCode and mix: the calls examples/zero_shot makes.
#include <pybind11/numpy.h>

#include <chrono>

#include "host/error.hpp"
#include "lib/io/checkpoint.hpp"
#include "lib/scene/camera_path.hpp"
#include "lib/scene/scene_meta.hpp"
#include "python/src/arrays.hpp"
#include "python/src/handles.hpp"
#include "python/src/path_args.hpp"

namespace stylerf::py {

namespace {

constexpr int kChunk = 8192;  // rays per content-render call: `stylerf stylize`'s default --chunk

ModelHandle open_model(const std::filesystem::path& checkpoint, const std::optional<SceneArg>& scene_arg) {
  const std::string path = path_arg(checkpoint, "path");
  scene::SceneOverrides o = scene_overrides(scene_arg, "scene");
  o.load_images = false;  // cameras only: stylising needs no photographs
  LibraryCall call;
  const io::Checkpoint ck = io::load_checkpoint(path, "");
  if (ck.kind != "style")
    throw host::Error("checkpoint " + path + " holds a '" + ck.kind +
                      "' stage, not a trained stylizer; train one with train_style");
  auto s = std::make_shared<ModelState>(ModelState{path, model::StyleModel::load(ck), {}, {}, {}, {}});
  s->scene = scene::open_scene_for(ck.meta.value("scene", nlohmann::json::object()), path, o).scene;
  s->vgg = nn::VggEncoder::load_default();
  s->encoder = std::make_unique<style::StyleEncoder>(s->model.dst, s->vgg);
  s->stats = std::make_unique<model::SceneStyleStats>(s->model, s->scene);
  return s;
}

}  // namespace

int supersample_of(const ModelState& s, const SupersampleArg& arg) {
  if (!arg) return s.model.inference_supersample;
  if (const auto* text = std::get_if<std::string>(&*arg)) {
    try {
      return model::parse_supersample(*text);
    } catch (const host::Error& e) {
      throw pyb::value_error("supersample: " + std::string(e.what()));
    }
  }
  const int n = std::get<int>(*arg);
  if (n < 1 || n > model::kMaxSupersample)
    throw pyb::value_error("supersample: must be in [1, " + std::to_string(model::kMaxSupersample) +
                           "] or 'quincunx', got " + std::to_string(n));
  return n;
}

namespace {

CodeHandle encode(const ModelHandle& s, const pyb::object& image) {
  CodeHandle c;
  c.owner = s;
  if (pyb::isinstance<pyb::str>(image) || pyb::hasattr(image, "__fspath__")) {
    c.source = pyb::str(image);
    if (c.source.empty()) throw pyb::value_error("image: an empty path; give an image file or an array");
    LibraryCall call;
    c.code = s->encoder->encode(c.source).code;  // the file as `stylize --style` reads it
  } else {
    const io::Image img = image_from_array(image, "image");
    c.source = "<array>";
    LibraryCall call;
    const io::Image square = io::resize(img, style::kStyleImageSize, style::kStyleImageSize);
    c.code = s->encoder->encode_image(io::to_tensor(square));
  }
  LibraryCall call;
  s->stats->attach(c.code);
  return c;
}

void check_owner(const ModelState& s, const CodeHandle& c, const char* arg) {
  if (c.owner.get() != &s)
    throw pyb::value_error(std::string(arg) + ": this StyleCode was encoded by another StyleModel (" + c.owner->path +
                           "); encode the style with this model");
}

// The zero-shot frame of examples/zero_shot and `stylize`: content, DST + decoder, over the background.
std::vector<float> stylize_frame(const ModelState& s, const scene::Camera& cam, const style::StyleCode& code, int n) {
  const auto content = s.model.render_camera_content(s.scene, cam, kChunk, nullptr, n);
  std::vector<float> rgb = s.model.stylize_camera(content, code, cam.width, cam.height);
  s.model.over_background(rgb, content, cam.width, cam.height);
  return rgb;
}

pyb::array_t<float> stylize(const ModelHandle& s, const ViewOrCamera& view, const CodeHandle& code,
                            const SupersampleArg& supersample) {
  check_owner(*s, code, "code");
  const int n = supersample_of(*s, supersample);
  const scene::Camera cam = resolve_view(s->scene, view);
  std::vector<float> rgb;
  {
    LibraryCall call;
    rgb = stylize_frame(*s, cam, code.code, n);
  }
  return to_array(std::move(rgb), cam.height, cam.width, 3);
}

// The same frame `repeats` times, each call timed in C++ (the bench's other side: what the Python call
// costs beyond the library's work).
std::vector<double> cpp_stylize_seconds(const ModelHandle& s, const ViewOrCamera& view, const CodeHandle& code,
                                        const SupersampleArg& supersample, int repeats) {
  check_owner(*s, code, "code");
  const int n = supersample_of(*s, supersample);
  const scene::Camera cam = resolve_view(s->scene, view);
  LibraryCall call;
  std::vector<double> out;
  for (int i = 0; i < repeats; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    const std::vector<float> rgb = stylize_frame(*s, cam, code.code, n);
    out.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  }
  return out;
}

// The stage-2 decoded RGB (unstylised) at the camera's size, and the depth and opacity of the same rays at
// the feature map's resolution (1/stride of it: the rays the model renders).
pyb::dict render(const ModelHandle& s, const ViewOrCamera& view) {
  const scene::Camera cam = resolve_view(s->scene, view);
  model::FeatureModel::DecodedView r;
  {
    LibraryCall call;
    r = s->model.features.render_decoded(s->scene, cam, kChunk);
  }
  pyb::dict d;
  d["rgb"] = to_array(std::move(r.rgb), r.height, r.width, 3);
  d["depth"] = to_array(std::move(r.map.depth), r.map.height, r.map.width, 1);
  d["opacity"] = to_array(std::move(r.map.acc), r.map.height, r.map.width, 1);
  d["stride"] = s->model.stride();
  return d;
}

CodeHandle mix(const std::vector<CodeHandle>& codes, const std::vector<float>& weights) {
  if (codes.empty()) throw pyb::value_error("codes: give at least one StyleCode");
  std::vector<style::StyleCode> raw;
  for (const auto& c : codes) {
    check_owner(*codes.front().owner, c, "codes");
    raw.push_back(c.code);
  }
  try {
    style::check_mix_weights(weights, codes.size(), "weights");
  } catch (const host::Error& e) {
    throw pyb::value_error(e.what());
  }
  CodeHandle out{{}, codes.front().owner, "mix"};
  LibraryCall call;
  out.code = style::mix_codes(raw, weights, "weights");
  out.owner->stats->attach(out.code);  // as `stylize --mix`: the mixed code gets its own statistics
  return out;
}

}  // namespace

void bind_model(pyb::module_& m) {
  pyb::class_<CodeHandle>(m, "StyleCode", "A style image's code under one StyleModel (zero-shot: no optimisation).")
      .def_readonly("source", &CodeHandle::source,
                    "Where the code came from: the image's path, '<array>' for an array, or 'mix'.")
      .def("__repr__", [](const CodeHandle& c) { return "StyleCode('" + c.source + "')"; });

  pyb::class_<ModelState, ModelHandle>(m, "StyleModel",
                                       "A trained style checkpoint on the scene it was trained on. A view is an index "
                                       "into cameras or a Camera.")
      .def_static("open", &open_model, pyb::arg("path"), pyb::arg("scene") = pyb::none(),
                  "Opens a train_style checkpoint. scene: the scene (a Scene or its folder) when it moved since "
                  "training; None: the folder the checkpoint records.")
      .def_readonly("path", &ModelState::path, "The checkpoint's path.")
      .def_property_readonly("supersample",
                             [](const ModelState& s) -> std::variant<int, std::string> {
                               if (s.model.inference_supersample == model::kQuincunx) return std::string("quincunx");
                               return s.model.inference_supersample;
                             },
                             "Rays per feature block that stylize uses by default: n (n x n) or 'quincunx'.")
      .def_property("strength", [](const ModelState& s) { return s.model.strength; },
                    [](ModelState& s, float v) {
                      try {
                        s.model.set_strength(v);
                      } catch (const host::Error& e) {
                        throw pyb::value_error(std::string("strength: ") + e.what());
                      }
                    },
                    "Stylisation strength in [0, 1]: each ray's stylised features blended with its own (the "
                    "checkpoint's by default, 1 unless set). Encode styles after setting it: a code carries the scene's "
                    "statistics at the strength it was encoded at.")
      .def_property_readonly("stride", [](const ModelState& s) { return s.model.stride(); },
                             "Pixels per feature-map cell along each side: the depth and opacity of render are at "
                             "1/stride of the image's resolution.")
      .def_property_readonly("cameras", [](const ModelState& s) {
        std::vector<scene::Camera> v;
        for (const auto& view : s.scene.test.empty() ? s.scene.train : s.scene.test) v.push_back(view.camera);
        return v;
      }, "The cameras a view index picks: the held-out views (the training views when there are none).")
      .def("path_cameras", [](const ModelState& s, int frames) {
        if (frames < 1) throw pyb::value_error("frames: must be >= 1");
        return scene::default_path(s.scene, frames);
      }, pyb::arg("frames") = 120, "The scene's default camera path: an orbit, or a spiral for forward-facing scenes.")
      .def("encode_style", &encode, pyb::arg("image"),
           "The code of a style image: a file path (read as `stylerf stylize --style` reads it) or an H x W x 3 "
           "array (float32 in [0, 1] or uint8).")
      .def("stylize", &stylize, pyb::arg("view"), pyb::arg("code"), pyb::arg("supersample") = pyb::none(),
           "The view stylised with code: H x W x 3 float32 in [0, 1]. supersample: rays per feature block, n (n x n, "
           "1 to 8) or 'quincunx'; None: the model's.")
      .def("render", &render, pyb::arg("view"),
           "The view without style: rgb (H x W x 3, the feature decoder's picture), and depth and opacity at 1/stride "
           "of that resolution (the rays the model renders).")
      .def("_cpp_stylize_seconds", &cpp_stylize_seconds, pyb::arg("view"), pyb::arg("code"),
           pyb::arg("supersample") = pyb::none(), pyb::arg("repeats") = 1,
           "The seconds of each of repeats stylize calls, timed in C++ (bench/python_stylize.py's other side).");

  m.def("mix", &mix, pyb::arg("codes"), pyb::arg("weights"),
        "The code sum_k weights[k] * codes[k] (weights >= 0 summing to 1, codes of one model): it interpolates the "
        "style transformation itself.");
}

}  // namespace stylerf::py
