// The per-device GEMM tuning database: CLBlast kernel parameters (from CLBlast's own tuners) and the
// tile parameters of our own GEMM kernel, keyed by CL_DEVICE_NAME.
//
// File format (tuning/clblast.json, embedded at build time; the user's copy from `stylerf tune` lives in
// $STYLERF_CACHE_DIR/clblast-tuning.json or ~/.cache/stylerf/clblast-tuning.json and wins per device):
//   {"format": "stylerf-clblast-tuning-1",
//    "devices": {"<CL_DEVICE_NAME>": {
//        "clblast": {"Xgemm": {"GEMMK": 0, "MWG": 64, ...}, "Copy": {...}, "Pad": {...}, "Transpose": {...},
//                    "Padtranspose": {...}, "XgemmDirect": {...}},
//        "recommended_engine": "own",
//        "own_gemm": {"mr": 6, "vw": 8, "nv": 2, "kc": 256, "wg": 1, "qt": 1},
//        "notes": {"source": "...", ...}}}}
#pragma once
#include <cstddef>
#include <map>
#include <optional>
#include <string>

namespace stylerf::host {

// Tile parameters of kernels/gemm.cl (see there): rows per work-item (mr), vector width (vw) and
// vectors per row (nv) of the tile, K chunk per launch (kc, 0 = all of K at once), work-group size
// along the row tiles (wg) and tiles along the columns per work-item (qt).
struct OwnGemmParams {
  int mr = 6, vw = 8, nv = 2, kc = 512, wg = 1, qt = 1;
  std::string build_options() const;  // "-DMR=6 -DVW=8 -DNV=2 -DQT=1"
  std::string describe() const;       // "mr=6 vw=8 nv=2 kc=512 wg=1 qt=1"
  void validate() const;              // throws Error on values the kernel cannot build
  bool operator==(const OwnGemmParams& o) const {
    return mr == o.mr && vw == o.vw && nv == o.nv && kc == o.kc && wg == o.wg && qt == o.qt;
  }
};

using ClblastParams = std::map<std::string, size_t>;  // parameter name -> value, e.g. "MWG" -> 64

struct DeviceTuning {
  std::map<std::string, ClblastParams> clblast;  // CLBlast kernel family ("Xgemm", "Copy", ...) -> parameters
  std::string recommended_engine;                // "own", "clblast-tuned", ... ("" = no recommendation)
  std::optional<OwnGemmParams> own_gemm;
  std::map<std::string, std::string> notes;      // free-form provenance: tool, date, measured GFLOP/s
};

class TuningDb {
 public:
  static constexpr const char* kFormat = "stylerf-clblast-tuning-1";

  // Parses the JSON text; `source` names it in errors ("embedded tuning/clblast.json", a path).
  static TuningDb parse(const std::string& text, const std::string& source);
  std::string dump() const;  // pretty JSON, stable key order

  const DeviceTuning* find(const std::string& device_name) const;
  void set(const std::string& device_name, const DeviceTuning& t) { devices_[device_name] = t; }
  // Adds other's devices, replacing the ones both have (per device, not per field).
  void merge_from(const TuningDb& other);
  const std::map<std::string, DeviceTuning>& devices() const { return devices_; }

 private:
  std::map<std::string, DeviceTuning> devices_;
};

// Where `stylerf tune` writes by default: cache_dir() + "/clblast-tuning.json".
std::string user_tuning_path();

// The database in effect: the embedded one, overlaid by the user file when it exists (a user file
// that does not parse is reported on stderr once and ignored, so a bad cache cannot stop the tool).
// Loaded once per process.
const TuningDb& active_tuning_db();
// The entry for the runtime's device in active_tuning_db(), or nullptr.
const DeviceTuning* active_device_tuning();

// Reads one JSON file written by a CLBlast tuner (clblast_<family>_32.json) and returns the CLBlast
// kernel family it tunes ("Xgemm", "XgemmDirect", "Copy", "Pad", "Transpose", "Padtranspose") with the
// best parameters and the best time in ms. Throws Error when the file is not a tuner result.
struct ClblastTunerResult {
  std::string kernel;
  ClblastParams params;
  double best_ms = 0.0;
  double work = 1.0;   // product of the tuner's problem sizes (arg_m, arg_n, arg_k present): compare best_ms / work
  std::string device;  // the "device" field the tuner recorded
};
ClblastTunerResult parse_clblast_tuner_json(const std::string& text, const std::string& source);

}  // namespace stylerf::host
