// `stylerf view`'s requests: JSON bodies checked field by field into what the renderer takes. Anything
// malformed (not JSON, a missing or mistyped field, NaN, a size out of range, a client name with other
// characters) is a RequestError with the HTTP status and a message saying what was wrong (docs/viewer.md).
#pragma once
#include <stdexcept>
#include <string>

#include "lib/scene/view_offset.hpp"
#include "lib/viewer/frame_renderer.hpp"

namespace stylerf::cli {

struct RequestError : std::runtime_error {
  int status;
  RequestError(int status_code, const std::string& message) : std::runtime_error(message), status(status_code) {}
};

constexpr int kMinSide = 16;
constexpr int kMaxSide = 4096;
constexpr int kMaxRecordFrames = 240;

struct RenderRequest {
  std::string client;
  viewer::FrameRequest frame;
  int frames = 0;  // /api/record only
};

// The body of /api/render and /api/record (record: `frames` too). views: the scene's training views.
RenderRequest parse_render_request(const std::string& body, int views, bool record);
// The body of /api/camera_path: its camera and side.
RenderRequest parse_camera_request(const std::string& body, int views);

}  // namespace stylerf::cli
