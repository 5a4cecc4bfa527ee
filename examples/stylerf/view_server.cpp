#include "examples/stylerf/view_server.hpp"

#include <httplib.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "examples/stylerf/frame_outputs.hpp"
#include "examples/stylerf/view_page.hpp"
#include "examples/stylerf/view_request.hpp"
#include "host/error.hpp"
#include "lib/io/image.hpp"
#include "lib/io/video.hpp"
#include "lib/scene/camera_path_json.hpp"

namespace stylerf::cli {

namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using Outcome = viewer::FairScheduler::Outcome;

void answer_json(httplib::Response& res, int status, const json& j) {
  res.status = status;
  res.set_content(j.dump(), "application/json");
}

void answer_error(httplib::Response& res, int status, const std::string& message) {
  answer_json(res, status, json{{"error", message}});
}

json style_rows(const viewer::StyleLibrary& styles) {
  json rows = json::array();
  for (const auto& e : styles.list()) rows.push_back({{"id", e.id}, {"name", e.name}, {"source", e.source}});
  return rows;
}

json info_json(const ViewContext& c) {
  const scene::ViewKind kind = scene::view_kind(c.scene);
  const scene::ViewLimits l = scene::view_limits(kind);
  const auto& cam = c.scene.train.front().camera;
  const int full = c.renderer.full_side();
  const auto& place = c.renderer.region_placement();
  return {{"scene", c.scene.name},
          {"kind", scene::view_kind_name(kind)},
          {"views", c.scene.train.size()},
          {"full", {{"width", cam.width}, {"height", cam.height}}},
          // Previews a quarter of the full side: a sixteenth of the rays, enough to see where one is going.
          {"preview_side", std::max(kMinSide, full / 4)},
          {"max_side", kMaxSide},
          {"limits", {{"yaw", l.yaw}, {"pitch", l.pitch}, {"zoom", l.zoom}}},
          {"device", c.device},
          {"styles", style_rows(c.styles)},
          {"max_upload_bytes", c.max_upload_bytes},
          {"region", {{"box", place.box}, {"sphere", place.sphere}}},
          {"token_required", !c.token.empty()}};
}

// Checks the request's style ids before any work is queued (404 names the id).
void check_styles(const ViewContext& c, const viewer::FrameRequest& f) {
  for (const std::string* id : {&f.style, &f.style_b})
    if (!id->empty() && !c.styles.find(*id)) throw RequestError(404, "no style with id '" + *id + "'");
}

// One frame through the scheduler under `client`. False (and `res` answered) when it did not render.
bool render_frame(ViewContext& c, const std::string& client, const viewer::FrameRequest& f, viewer::Frame& out,
                  httplib::Response& res) {
  const Outcome o = c.scheduler.run(client, [&](const std::atomic<bool>& cancel) { out = c.renderer.render(f, &cancel); });
  if (o == Outcome::Superseded) {
    answer_error(res, 409, "superseded");
    return false;
  }
  if (o == Outcome::Stopped) {
    answer_error(res, 503, "the server is stopping");
    return false;
  }
  return true;
}

void handle_render(ViewContext& c, const httplib::Request& req, httplib::Response& res) {
  const RenderRequest r = parse_render_request(req.body, int(c.scene.train.size()), false);
  check_styles(c, r.frame);
  viewer::Frame f;
  if (!render_frame(c, r.client, r.frame, f, res)) return;
  res.set_header("X-Render-Ms", std::to_string(f.render_s * 1e3));
  res.set_header("X-Content-Cached", f.content_cached ? "1" : "0");
  res.set_header("X-Side", std::to_string(r.frame.side));
  res.set_header("Cache-Control", "no-store");
  res.set_content(io::encode_png(f.image), "image/png");
}

void handle_upload(ViewContext& c, const httplib::Request& req, httplib::Response& res) {
  if (req.body.size() > c.max_upload_bytes)
    throw RequestError(413, "the image is larger than " + std::to_string(c.max_upload_bytes) + " bytes");
  const std::string name = viewer::clean_style_name(req.has_param("name") ? req.get_param_value("name") : "upload");
  std::string id;
  try {
    id = c.styles.add_upload(req.body, fs::path(name).stem().string());
  } catch (const host::Error& e) {
    throw RequestError(415, e.what());
  }
  // Encoded now (zero-shot: once), so the page's first frame in this style costs a frame only.
  const auto t = std::chrono::steady_clock::now();
  const Outcome o = c.scheduler.run("upload-" + id, [&](const std::atomic<bool>&) { c.renderer.prepare_style(id); });
  if (o != Outcome::Done) return answer_error(res, 503, "the server is stopping");
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
  const auto e = c.styles.find(id);
  answer_json(res, 201, {{"id", id}, {"name", e->name}, {"source", e->source}, {"encode_ms", ms}});
}

void handle_camera_path(ViewContext& c, const httplib::Request& req, httplib::Response& res) {
  const RenderRequest r = parse_camera_request(req.body, int(c.scene.train.size()));
  const scene::Camera cam = scene::offset_camera(c.scene, r.frame.camera, r.frame.side);
  res.set_content(scene::camera_path_json_text({cam}, 30), "application/json");
}

// The orbit's frames rendered one at a time through the scheduler (other tabs are served between them),
// written as PNGs and made into an mp4 by the same call as stylize's video.
void handle_record(ViewContext& c, const httplib::Request& req, httplib::Response& res) {
  const RenderRequest r = parse_render_request(req.body, int(c.scene.train.size()), true);
  check_styles(c, r.frame);
  static std::atomic<int> counter{0};
  const fs::path dir = fs::path(c.work_dir) / ("record_" + std::to_string(counter++));
  fs::create_directories(dir);
  struct Cleanup {
    fs::path p;
    ~Cleanup() {
      std::error_code ec;
      fs::remove_all(p, ec);
    }
  } cleanup{dir};
  const auto offsets = scene::orbit_offsets(r.frame.camera, scene::view_kind(c.scene), r.frames);
  for (size_t i = 0; i < offsets.size(); ++i) {
    viewer::FrameRequest f = r.frame;
    f.camera = offsets[i];
    viewer::Frame frame;
    if (!render_frame(c, r.client + "-record", f, frame, res)) return;
    io::save_png(numbered(dir.string(), "frame_", int(i), 4, ".png"), frame.image);
  }
  std::ostringstream log;
  if (!io::write_video(dir.string(), "frame_%04d.png", "orbit.mp4", 30, log))
    return answer_error(res, 503, "recording needs ffmpeg on PATH: " + log.str());
  std::ifstream f(dir / "orbit.mp4", std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  res.set_header("Content-Disposition", "attachment; filename=\"stylerf_orbit.mp4\"");
  res.set_content(bytes, "video/mp4");
}

// Wraps a handler: RequestError -> its status, host::Error -> 400, anything else -> 500; never a crash.
httplib::Server::Handler guarded(ViewContext& c, void (*fn)(ViewContext&, const httplib::Request&, httplib::Response&)) {
  return [&c, fn](const httplib::Request& req, httplib::Response& res) {
    try {
      fn(c, req, res);
    } catch (const RequestError& e) {
      answer_error(res, e.status, e.what());
    } catch (const host::Error& e) {
      answer_error(res, 400, e.what());
    } catch (const std::exception& e) {
      std::cerr << "view: " << req.method << " " << req.path << ": " << e.what() << "\n";
      answer_error(res, 500, e.what());
    }
  };
}

void install_page(httplib::Server& s) {
  for (const PageFile& f : view_page_files()) {
    const std::string path = f.path;
    s.Get(path, [&f](const httplib::Request&, httplib::Response& res) { res.set_content(f.body, f.type); });
    if (path == "/index.html")
      s.Get("/", [&f](const httplib::Request&, httplib::Response& res) { res.set_content(f.body, f.type); });
  }
}

}  // namespace

void install_view_routes(httplib::Server& s, ViewContext& c) {
  s.set_pre_routing_handler([&c](const httplib::Request& req, httplib::Response& res) {
    if (c.token.empty()) return httplib::Server::HandlerResponse::Unhandled;
    const std::string given =
        req.has_header("X-Stylerf-Token") ? req.get_header_value("X-Stylerf-Token") : req.get_param_value("token");
    if (given == c.token) return httplib::Server::HandlerResponse::Unhandled;
    answer_error(res, 403, "this server needs the token printed when it started (?token=... or X-Stylerf-Token)");
    return httplib::Server::HandlerResponse::Handled;
  });
  install_page(s);
  s.Get("/api/info", [&c](const httplib::Request&, httplib::Response& res) { answer_json(res, 200, info_json(c)); });
  s.Get("/api/styles", [&c](const httplib::Request&, httplib::Response& res) { answer_json(res, 200, style_rows(c.styles)); });
  s.Get(R"(/api/styles/([A-Za-z0-9]{1,16})/thumb)", [&c](const httplib::Request& req, httplib::Response& res) {
    const auto e = c.styles.find(req.matches[1]);
    if (!e) return answer_error(res, 404, "no style with id '" + std::string(req.matches[1]) + "'");
    res.set_content(e->thumb_png, "image/png");
  });
  s.Post("/api/styles", guarded(c, handle_upload));
  s.Post("/api/render", guarded(c, handle_render));
  s.Post("/api/camera_path", guarded(c, handle_camera_path));
  s.Post("/api/record", guarded(c, handle_record));
  s.set_error_handler([](const httplib::Request& req, httplib::Response& res) {
    if (!res.body.empty()) return;  // a handler's own answer
    const std::string what = res.status == 413 ? "the body is larger than this server accepts"
                             : res.status == 404 ? "no such page or endpoint: " + req.method + " " + req.path
                                                 : "request refused";
    answer_error(res, res.status, what);
  });
  s.set_exception_handler([](const httplib::Request& req, httplib::Response& res, std::exception_ptr ep) {
    std::string what = "internal error";
    try {
      if (ep) std::rethrow_exception(ep);
    } catch (const std::exception& e) {
      what = e.what();
    } catch (...) {
    }
    std::cerr << "view: " << req.method << " " << req.path << ": " << what << "\n";
    answer_error(res, 500, what);
  });
}

}  // namespace stylerf::cli
