// Plain struct fields to and from JSON by their own names: one list of names serves both directions, so
// a field cannot be written and then forgotten when read (or read under another key).
//
//   #define MY_FIELDS batch, lr_grid, seed
//   STYLERF_JSON_PUT_FIELDS(j, cfg, MY_FIELDS);   // j["batch"] = cfg.batch; ...
//   STYLERF_JSON_GET_FIELDS(j, cfg, MY_FIELDS);   // j.at("batch").get_to(cfg.batch); ... (missing: throws)
//
// Reading throws nlohmann's exceptions on a missing key or a wrong type; callers turn them into an Error
// naming the file. Fields with their own spelling (enums as names, renamed or optional keys) are written
// out beside these.
#pragma once
#include <nlohmann/json.hpp>

#define STYLERF_JSON_PUT_ONE(field) stylerf_json_[#field] = stylerf_obj_.field;
#define STYLERF_JSON_GET_ONE(field) stylerf_json_.at(#field).get_to(stylerf_obj_.field);

#define STYLERF_JSON_PUT_FIELDS(json_, obj_, ...)                                        \
  do {                                                                                   \
    nlohmann::json& stylerf_json_ = (json_);                                             \
    const auto& stylerf_obj_ = (obj_);                                                   \
    NLOHMANN_JSON_EXPAND(NLOHMANN_JSON_PASTE(STYLERF_JSON_PUT_ONE, __VA_ARGS__))         \
  } while (0)

#define STYLERF_JSON_GET_FIELDS(json_, obj_, ...)                                        \
  do {                                                                                   \
    const nlohmann::json& stylerf_json_ = (json_);                                       \
    auto& stylerf_obj_ = (obj_);                                                         \
    NLOHMANN_JSON_EXPAND(NLOHMANN_JSON_PASTE(STYLERF_JSON_GET_ONE, __VA_ARGS__))         \
  } while (0)
