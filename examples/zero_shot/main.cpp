// Zero-shot stylisation from research code, with the library only: load a style checkpoint, encode one
// style image (no optimisation), stylise one test view of the scene the checkpoint was trained on, and
// write a PNG.
//   stylerf_zero_shot STYLE.ckpt STYLE_IMAGE OUT.png [VIEW]
#include <cstdlib>
#include <iostream>

#include "host/runtime.hpp"
#include "lib/io/checkpoint.hpp"
#include "lib/io/image.hpp"
#include "lib/model/scene_style_stats.hpp"
#include "lib/model/style_model.hpp"
#include "lib/scene/scene_meta.hpp"
#include "lib/style/style_encoder.hpp"

int main(int argc, char** argv) {
  using namespace stylerf;
  if (argc < 4) {
    std::cerr << "usage: " << argv[0] << " STYLE.ckpt STYLE_IMAGE OUT.png [VIEW]\n";
    return 2;
  }
  try {
    host::Runtime::init();  // STYLERF_DEVICE picks the device
    const io::Checkpoint ck = io::load_checkpoint(argv[1], "style");
    const model::StyleModel m = model::StyleModel::load(ck);

    // The scene's cameras (no images needed), from where the checkpoint says it was trained.
    const nlohmann::json meta = ck.meta.value("scene", nlohmann::json::object());
    scene::SceneOverrides o;
    o.load_images = false;
    const scene::Scene scene = scene::open_scene_for(meta, argv[1], o).scene;
    const auto& views = scene.test.empty() ? scene.train : scene.test;
    const scene::Camera cam = views.at(argc > 4 ? size_t(std::atoi(argv[4])) % views.size() : 0).camera;

    // The style's code: VGG relu3_1 statistics and the transformation T (no cache here).
    nn::VggEncoder vgg = nn::VggEncoder::load_default();
    style::StyleEncoder encoder(m.dst, vgg);
    style::StyleCode code = encoder.encode(argv[2]).code;
    model::SceneStyleStats(m, scene).attach(code);  // one re-normalisation for the scene's every frame

    // Content once (style-independent), then any number of styles on it.
    const auto content = m.render_camera_content(scene, cam, 4096, nullptr, m.inference_supersample);
    std::vector<float> rgb = m.stylize_camera(content, code, cam.width, cam.height);
    m.over_background(rgb, content, cam.width, cam.height);

    io::Image img;
    img.width = cam.width;
    img.height = cam.height;
    img.data.resize(rgb.size());
    const size_t plane = size_t(cam.width) * cam.height;
    for (size_t i = 0; i < plane; ++i)
      for (int c = 0; c < 3; ++c) img.data[c * plane + i] = rgb[3 * i + c];
    io::save_png(argv[3], img);
    std::cout << "wrote " << argv[3] << " (" << cam.width << "x" << cam.height << ")\n";
    host::Runtime::shutdown();
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 1;
  }
}
