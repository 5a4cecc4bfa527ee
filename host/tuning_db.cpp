#include "host/tuning_db.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <sstream>

#include "host/embedded.hpp"
#include "host/error.hpp"
#include "host/files.hpp"
#include "host/runtime.hpp"

namespace stylerf::host {

using nlohmann::json;

std::string OwnGemmParams::build_options() const {
  return "-DMR=" + std::to_string(mr) + " -DVW=" + std::to_string(vw) + " -DNV=" + std::to_string(nv) +
         " -DQT=" + std::to_string(qt);
}

std::string OwnGemmParams::describe() const {
  std::ostringstream o;
  o << "mr=" << mr << " vw=" << vw << " nv=" << nv << " kc=" << kc << " wg=" << wg << " qt=" << qt;
  return o.str();
}

void OwnGemmParams::validate() const {
  // Bounds keep the register tile meaningful (mr*nv vectors of accumulators) and the build small.
  if (mr < 1 || mr > 16 || (vw != 4 && vw != 8 && vw != 16) || nv < 1 || nv > 8 || kc < 0 || wg < 1 || wg > 256 ||
      qt < 1 || qt > 64)
    throw Error("own GEMM parameters out of range: " + describe() +
                " (mr 1..16, vw 4|8|16, nv 1..8, kc >= 0, wg 1..256, qt 1..64)");
}

namespace {

OwnGemmParams own_from_json(const json& j, const std::string& where) {
  OwnGemmParams p;
  auto get = [&](const char* key, int& v) {
    if (j.contains(key)) {
      if (!j[key].is_number_integer()) throw Error(where + ": own_gemm." + key + " must be an integer");
      v = j[key].get<int>();
    }
  };
  get("mr", p.mr);
  get("vw", p.vw);
  get("nv", p.nv);
  get("kc", p.kc);
  get("wg", p.wg);
  get("qt", p.qt);
  p.validate();
  return p;
}

json own_to_json(const OwnGemmParams& p) {
  return json{{"mr", p.mr}, {"vw", p.vw}, {"nv", p.nv}, {"kc", p.kc}, {"wg", p.wg}, {"qt", p.qt}};
}

}  // namespace

TuningDb TuningDb::parse(const std::string& text, const std::string& source) {
  json j;
  try {
    j = json::parse(text);
  } catch (const json::exception& e) {
    throw Error(source + ": not valid JSON: " + e.what());
  }
  if (!j.is_object() || j.value("format", "") != kFormat)
    throw Error(source + ": not a stylerf tuning database (expected \"format\": \"" + std::string(kFormat) + "\")");
  TuningDb db;
  if (!j.contains("devices")) return db;
  if (!j["devices"].is_object()) throw Error(source + ": \"devices\" must be an object");
  for (const auto& [name, dj] : j["devices"].items()) {
    const std::string where = source + ": device '" + name + "'";
    if (!dj.is_object()) throw Error(where + " must be an object");
    DeviceTuning t;
    if (dj.contains("clblast")) {
      for (const auto& [kernel, pj] : dj["clblast"].items()) {
        if (!pj.is_object()) throw Error(where + ": clblast." + kernel + " must be an object");
        ClblastParams params;
        for (const auto& [pname, v] : pj.items()) {
          if (!v.is_number_unsigned() && !(v.is_number_integer() && v.get<long long>() >= 0))
            throw Error(where + ": clblast." + kernel + "." + pname + " must be a non-negative integer");
          params[pname] = v.get<size_t>();
        }
        t.clblast[kernel] = params;
      }
    }
    t.recommended_engine = dj.value("recommended_engine", "");
    if (dj.contains("own_gemm")) t.own_gemm = own_from_json(dj["own_gemm"], where);
    if (dj.contains("notes") && dj["notes"].is_object())
      for (const auto& [k, v] : dj["notes"].items()) t.notes[k] = v.is_string() ? v.get<std::string>() : v.dump();
    db.devices_[name] = t;
  }
  return db;
}

std::string TuningDb::dump() const {
  json devices = json::object();
  for (const auto& [name, t] : devices_) {
    json d = json::object();
    json cl = json::object();
    for (const auto& [kernel, params] : t.clblast) {
      json pj = json::object();
      for (const auto& [pname, v] : params) pj[pname] = v;
      cl[kernel] = pj;
    }
    d["clblast"] = cl;
    if (!t.recommended_engine.empty()) d["recommended_engine"] = t.recommended_engine;
    if (t.own_gemm) d["own_gemm"] = own_to_json(*t.own_gemm);
    if (!t.notes.empty()) d["notes"] = t.notes;
    devices[name] = d;
  }
  json j = {{"format", kFormat}, {"devices", devices}};
  return j.dump(2) + "\n";
}

const DeviceTuning* TuningDb::find(const std::string& device_name) const {
  auto it = devices_.find(device_name);
  return it == devices_.end() ? nullptr : &it->second;
}

void TuningDb::merge_from(const TuningDb& other) {
  for (const auto& [name, t] : other.devices_) devices_[name] = t;
}

std::string user_tuning_path() { return cache_dir() + "/clblast-tuning.json"; }

const TuningDb& active_tuning_db() {
  static const TuningDb db = [] {
    TuningDb d = TuningDb::parse(embedded_tuning_db(), "embedded tuning/clblast.json");
    const std::string path = user_tuning_path();
    std::error_code ec;
    if (std::filesystem::exists(path, ec)) {
      try {
        d.merge_from(TuningDb::parse(read_file(path), path));
      } catch (const std::exception& e) {
        std::cerr << "stylerf: ignoring the user tuning file: " << e.what() << "\n";
      }
    }
    return d;
  }();
  return db;
}

const DeviceTuning* active_device_tuning() {
  return active_tuning_db().find(Runtime::instance().device().name);
}

ClblastTunerResult parse_clblast_tuner_json(const std::string& text, const std::string& source) {
  json j;
  try {
    j = json::parse(text);
  } catch (const json::exception& e) {
    throw Error(source + ": not valid JSON: " + e.what());
  }
  if (!j.is_object() || !j.contains("kernel_family") || !j.contains("results") || !j["results"].is_array())
    throw Error(source + ": not a CLBlast tuner result (needs kernel_family and results)");
  // kernel_family is the tuner's name (xgemm_1, xgemm_2, xgemm_direct_1, copy, pad, transpose, ...);
  // OverrideParameters wants the database kernel family.
  const std::string fam = j["kernel_family"].get<std::string>();
  auto starts = [&](const char* p) { return fam.rfind(p, 0) == 0; };
  ClblastTunerResult r;
  if (starts("xgemm_direct")) r.kernel = "XgemmDirect";
  else if (starts("xgemm")) r.kernel = "Xgemm";
  else if (starts("copy")) r.kernel = "Copy";
  else if (starts("padtranspose")) r.kernel = "Padtranspose";
  else if (starts("pad")) r.kernel = "Pad";
  else if (starts("transpose")) r.kernel = "Transpose";
  else throw Error(source + ": unsupported kernel family '" + fam + "'");
  r.device = j.value("device", "");
  // Runs of one tuner at different problem sizes compare by time per unit of work.
  for (const char* arg : {"arg_m", "arg_n", "arg_k"})
    if (j.contains(arg) && j[arg].is_string()) r.work *= std::max(1.0, std::atof(j[arg].get<std::string>().c_str()));
  bool found = false;
  for (const auto& res : j["results"]) {
    const double t = res.value("time", 0.0);
    if (t <= 0.0 || !res.contains("parameters")) continue;
    if (found && t >= r.best_ms) continue;
    ClblastParams p;
    for (const auto& [k, v] : res["parameters"].items())
      if (k != "PRECISION") p[k] = v.get<size_t>();  // the tuner records the precision among the parameters
    r.params = p;
    r.best_ms = t;
    found = true;
  }
  if (!found) throw Error(source + ": no successful configuration in the tuner results");
  return r;
}

}  // namespace stylerf::host
