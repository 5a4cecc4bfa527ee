// `stylerf view`'s HTTP side: the page and the API of docs/viewer.md on a cpp-httplib server. Every piece
// of device work (a frame, a style's first encoding) runs through one FairScheduler, one at a time; the
// HTTP threads only parse, wait and write, so a slow or vanished client holds nothing but its own thread.
#pragma once
#include <string>

#include "lib/model/style_model.hpp"
#include "lib/scene/scene.hpp"
#include "lib/viewer/fair_scheduler.hpp"
#include "lib/viewer/frame_renderer.hpp"
#include "lib/viewer/style_library.hpp"

namespace httplib {
class Server;
}

namespace stylerf::cli {

struct ViewContext {
  const scene::Scene& scene;
  viewer::StyleLibrary& styles;
  viewer::FrameRenderer& renderer;
  viewer::FairScheduler& scheduler;
  std::string device;        // the device's name, shown by the page
  std::string token;         // empty: none required (loopback)
  size_t max_upload_bytes = 16u << 20;
  std::string work_dir;      // the server's own scratch folder (recordings)
};

// Registers the page, the API, the token check and the error answers on `server`.
void install_view_routes(httplib::Server& server, ViewContext& ctx);

}  // namespace stylerf::cli
