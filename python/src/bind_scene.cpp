// Camera and Scene.
#include <pybind11/numpy.h>

#include "host/error.hpp"
#include "lib/scene/camera_path.hpp"
#include "python/src/arrays.hpp"
#include "python/src/handles.hpp"
#include "python/src/path_args.hpp"

namespace stylerf::py {

namespace {

// c2w: 3 x 4 or 4 x 4 (last row 0 0 0 1), camera-to-world in OpenGL axes (the camera looks down -z).
scene::Camera make_camera(const pyb::handle& c2w, float fx, float fy, float cx, float cy, int w, int h) {
  if (w < 1 || h < 1) throw pyb::value_error("w, h: the image size must be positive (got " + std::to_string(w) + " x " + std::to_string(h) + ")");
  for (auto [v, name] : {std::pair{fx, "fx"}, std::pair{fy, "fy"}})
    if (!(v > 0) || !std::isfinite(v)) throw pyb::value_error(std::string(name) + ": must be a positive focal length in pixels");
  if (!std::isfinite(cx) || !std::isfinite(cy)) throw pyb::value_error("cx, cy: must be finite");
  const bool square = pyb::isinstance<pyb::array>(c2w) && pyb::reinterpret_borrow<pyb::array>(c2w).ndim() == 2 &&
                      pyb::reinterpret_borrow<pyb::array>(c2w).shape(0) == 4;
  const auto a = float_array(c2w, {square ? 4L : 3L, 4L}, "c2w");
  if (square && (a.at(3, 0) != 0 || a.at(3, 1) != 0 || a.at(3, 2) != 0 || a.at(3, 3) != 1))
    throw pyb::value_error("c2w: a 4 x 4 matrix must end in the row 0 0 0 1");
  scene::Camera cam;
  double pose[3][4];
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) pose[r][c] = cam.c2w[r][c] = a.at(r, c);
  try {
    scene::check_pose(pose, "c2w");
  } catch (const host::Error& e) {
    throw pyb::value_error(e.what());
  }
  cam.fx = fx, cam.fy = fy, cam.cx = cx, cam.cy = cy, cam.width = w, cam.height = h;
  return cam;
}

pyb::array_t<float> c2w_array(const scene::Camera& cam) {
  std::vector<float> v;
  for (const auto& row : cam.c2w) v.insert(v.end(), row, row + 4);
  v.insert(v.end(), {0, 0, 0, 1});
  return to_array(std::move(v), 4, 4, 1);
}

}  // namespace

scene::Camera resolve_view(const scene::Scene& scene, const ViewOrCamera& v) {
  if (const auto* cam = std::get_if<scene::Camera>(&v)) return *cam;
  const auto& views = scene.test.empty() ? scene.train : scene.test;
  const int i = std::get<int>(v), n = int(views.size());
  if (i < -n || i >= n)
    throw pyb::index_error("view " + std::to_string(i) + " is out of range: the scene has " + std::to_string(n) +
                           (scene.test.empty() ? " training" : " held-out") + " views");
  return views[size_t(i < 0 ? i + n : i)].camera;
}

void bind_scene(pyb::module_& m) {
  pyb::class_<scene::Camera>(m, "Camera",
                             "A pinhole camera: c2w camera-to-world (3 x 4 or 4 x 4, OpenGL axes: it looks down -z), "
                             "intrinsics in pixels.")
      .def(pyb::init(&make_camera), pyb::arg("c2w"), pyb::arg("fx"), pyb::arg("fy"), pyb::arg("cx"), pyb::arg("cy"),
           pyb::arg("w"), pyb::arg("h"),
           "A camera from its pose (a rigid 3 x 4 or 4 x 4 matrix, float32 or float64), focal lengths, principal "
           "point and image size in pixels.")
      .def_property_readonly("c2w", &c2w_array, "The 4 x 4 camera-to-world matrix (a copy).")
      .def_readonly("fx", &scene::Camera::fx, "Horizontal focal length in pixels.")
      .def_readonly("fy", &scene::Camera::fy, "Vertical focal length in pixels.")
      .def_readonly("cx", &scene::Camera::cx, "Principal point, x in pixels.")
      .def_readonly("cy", &scene::Camera::cy, "Principal point, y in pixels.")
      .def_readonly("width", &scene::Camera::width, "Image width in pixels.")
      .def_readonly("height", &scene::Camera::height, "Image height in pixels.")
      .def("resized", &scene::Camera::resized, pyb::arg("w"), pyb::arg("h"),
           "The same camera for a w x h image (intrinsics scaled with it).")
      .def("with_longer_side", &scene::Camera::with_longer_side, pyb::arg("size"),
           "The same camera with its longer side size pixels and its aspect kept (size <= 0: unchanged).")
      .def("__repr__", [](const scene::Camera& c) {
        return "Camera(" + std::to_string(c.width) + "x" + std::to_string(c.height) + ", fx=" + std::to_string(c.fx) + ")";
      });

  pyb::class_<SceneHandle, std::shared_ptr<SceneHandle>>(m, "Scene", "A scene folder (Blender, LLFF, COLMAP or nerfstudio).")
      .def_static("open", &open_scene, pyb::arg("path"), pyb::arg("downsample") = pyb::none(),
                  "Loads the scene folder. downsample: the image downsample factor (None: the paper's resolution, "
                  "Blender 1, LLFF 4, COLMAP and nerfstudio 1).")
      .def_property_readonly("name", [](const SceneHandle& h) { return h.scene.name; }, "The scene's name.")
      .def_property_readonly("format", [](const SceneHandle& h) { return h.scene.format; },
                             "The folder's format as the loader found it: blender, or llff, colmap or nerfstudio with "
                             "-forward or -object.")
      .def_property_readonly("path", [](const SceneHandle& h) { return h.dir; }, "The folder, as given to open.")
      .def_property_readonly("downsample", [](const SceneHandle& h) { return h.options.downsample; },
                             "The downsample factor its images were loaded at.")
      .def_property_readonly("train_cameras", [](const SceneHandle& h) {
        std::vector<scene::Camera> v;
        for (const auto& view : h.scene.train) v.push_back(view.camera);
        return v;
      }, "The training views' cameras.")
      .def_property_readonly("test_cameras", [](const SceneHandle& h) {
        std::vector<scene::Camera> v;
        for (const auto& view : h.scene.test) v.push_back(view.camera);
        return v;
      }, "The held-out views' cameras (empty when the scene holds none out).")
      .def("path_cameras", [](const SceneHandle& h, int frames) { return scene::default_path(h.scene, frames); },
           pyb::arg("frames") = 120,
           "The scene's default camera path: an orbit, or a spiral for forward-facing scenes.")
      .def("__repr__", [](const SceneHandle& h) {
        return "Scene('" + h.dir + "', " + h.scene.format + ", " + std::to_string(h.scene.train.size()) + " train / " +
               std::to_string(h.scene.test.size()) + " test views)";
      });
}

}  // namespace stylerf::py
