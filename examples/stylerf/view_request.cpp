#include "examples/stylerf/view_request.hpp"

#include <cctype>
#include <cmath>
#include <nlohmann/json.hpp>

namespace stylerf::cli {

namespace {

using nlohmann::json;

json parse_object(const std::string& body) {
  json j = json::parse(body, nullptr, false);
  if (j.is_discarded()) throw RequestError(400, "the body is not JSON");
  if (!j.is_object()) throw RequestError(400, "the body must be a JSON object");
  return j;
}

// A finite number at j[key]; `fallback` when absent and not required.
double number(const json& j, const char* key, bool required, double fallback = 0) {
  if (!j.contains(key) || j[key].is_null()) {
    if (required) throw RequestError(400, std::string("'") + key + "' is missing");
    return fallback;
  }
  if (!j[key].is_number()) throw RequestError(400, std::string("'") + key + "' must be a number");
  const double v = j[key].get<double>();
  if (!std::isfinite(v)) throw RequestError(400, std::string("'") + key + "' must be finite");
  return v;
}

int integer(const json& j, const char* key, int lo, int hi) {
  if (!j.contains(key)) throw RequestError(400, std::string("'") + key + "' is missing");
  if (!j[key].is_number_integer()) throw RequestError(400, std::string("'") + key + "' must be an integer");
  const int64_t v = j[key].get<int64_t>();
  if (v < lo || v > hi)
    throw RequestError(400, std::string("'") + key + "' must be in [" + std::to_string(lo) + ", " + std::to_string(hi) +
                                "], got " + std::to_string(v));
  return int(v);
}

std::string text(const json& j, const char* key, bool required) {
  if (!j.contains(key) || j[key].is_null()) {
    if (required) throw RequestError(400, std::string("'") + key + "' is missing");
    return "";
  }
  if (!j[key].is_string()) throw RequestError(400, std::string("'") + key + "' must be a string");
  return j[key].get<std::string>();
}

scene::ViewOffset parse_camera(const json& j, int views) {
  if (!j.contains("camera") || !j["camera"].is_object()) throw RequestError(400, "'camera' must be an object");
  const json& c = j["camera"];
  scene::ViewOffset o;
  o.view = integer(c, "view", 0, views - 1);
  o.yaw = number(c, "yaw", false);
  o.pitch = number(c, "pitch", false);
  o.zoom = number(c, "zoom", false);
  return o;
}

void check_client(const std::string& client) {
  if (client.empty() || client.size() > 64) throw RequestError(400, "'client' must have 1 to 64 characters");
  for (char ch : client)
    if (!(std::isalnum(static_cast<unsigned char>(ch)) || ch == '-' || ch == '_'))
      throw RequestError(400, "'client' may hold letters, digits, '-' and '_' only");
}

void parse_region(const json& j, viewer::FrameRequest& f) {
  if (!j.contains("region") || j["region"].is_null()) return;
  const json& r = j["region"];
  if (!r.is_object()) throw RequestError(400, "'region' must be an object or null");
  f.region_shape = text(r, "shape", true);
  if (f.region_shape != "box" && f.region_shape != "sphere")
    throw RequestError(400, "'region.shape' must be \"box\" or \"sphere\"");
  f.region_scale = number(r, "scale", false, 1.0);
  if (f.region_scale < 0.05 || f.region_scale > 4) throw RequestError(400, "'region.scale' must be in [0.05, 4]");
  if (f.style_b.empty()) throw RequestError(400, "a region needs 'style_b' (the style inside it)");
}

}  // namespace

RenderRequest parse_camera_request(const std::string& body, int views) {
  const json j = parse_object(body);
  RenderRequest r;
  r.frame.camera = parse_camera(j, views);
  r.frame.side = integer(j, "side", kMinSide, kMaxSide);
  return r;
}

RenderRequest parse_render_request(const std::string& body, int views, bool record) {
  const json j = parse_object(body);
  RenderRequest r;
  r.client = text(j, "client", true);
  check_client(r.client);
  r.frame.camera = parse_camera(j, views);
  r.frame.side = integer(j, "side", kMinSide, kMaxSide);
  r.frame.style = text(j, "style", true);
  r.frame.style_b = text(j, "style_b", false);
  r.frame.mix = number(j, "mix", false, 0.0);
  if (r.frame.mix < 0 || r.frame.mix > 1) throw RequestError(400, "'mix' must be in [0, 1]");
  parse_region(j, r.frame);
  if (record) r.frames = integer(j, "frames", 2, kMaxRecordFrames);
  return r;
}

}  // namespace stylerf::cli
