// LPIPS between two images and the consistency measurement of a stylised path.
#include <cmath>
#include <map>
#include <mutex>

#include "host/error.hpp"
#include "lib/eval/lpips.hpp"
#include "lib/eval/path_consistency.hpp"
#include "lib/eval/path_frames.hpp"
#include "python/src/arrays.hpp"
#include "python/src/handles.hpp"

namespace stylerf::py {

namespace {

// Each net's weights are loaded once per process, at its first use.
const eval::Lpips& lpips_net(const std::string& name) {
  static std::map<std::string, eval::Lpips> nets;
  static std::mutex mu;
  const eval::LpipsNet net = eval::parse_lpips_net(name);
  std::lock_guard<std::mutex> lock(mu);
  auto it = nets.find(name);
  if (it == nets.end()) it = nets.emplace(name, eval::Lpips::load_default(net)).first;
  return it->second;
}

void check_net(const std::string& net) {
  if (net != "vgg" && net != "alex") throw pyb::value_error("net: '" + net + "' is not one of: vgg, alex");
}

double lpips(const pyb::object& a, const pyb::object& b, const std::string& net) {
  check_net(net);
  const io::Image ia = image_from_array(a, "a"), ib = image_from_array(b, "b");
  if (ia.width != ib.width || ia.height != ib.height)
    throw pyb::value_error("a, b: the images differ in size (" + std::to_string(ia.height) + " x " +
                           std::to_string(ia.width) + " and " + std::to_string(ib.height) + " x " +
                           std::to_string(ib.width) + ")");
  LibraryCall call;
  return lpips_net(net).distance(ia, ib);
}

// lpips is None when it was not measured (consistency(lpips=None)).
pyb::dict range_dict(const eval::RangeScore& r, bool measured_lpips) {
  pyb::dict d;
  d["k"] = r.k;
  d["rmse"] = r.rmse;
  d["lpips"] = measured_lpips ? pyb::object(pyb::float_(r.lpips)) : pyb::none();
  d["valid_fraction"] = r.valid_fraction;
  d["pairs"] = int(r.pairs.size());
  d["skipped"] = r.skipped;
  return d;
}

// `stylerf eval consistency --method stylerf` for a code already encoded: the path's first `frames`
// frames, warped by the scene's own geometry; RMSE, and LPIPS unless lpips_net is None.
pyb::dict consistency(const ModelHandle& s, const CodeHandle& code, int frames, int path_frames,
                      std::optional<int> size, std::optional<std::string> lpips_name, const SupersampleArg& supersample) {
  if (code.owner != s) throw pyb::value_error("code: this StyleCode was encoded by another StyleModel");
  if (frames < 8 || frames > 1000) throw pyb::value_error("frames: must be in [8, 1000] (the long range compares t with t - 7)");
  if (path_frames < frames || path_frames > 100000) throw pyb::value_error("path_frames: must be in [frames, 100000]");
  if (size && (*size < 1 || *size > 4096)) throw pyb::value_error("size: must be in [1, 4096], or None for the scene's");
  if (lpips_name) check_net(*lpips_name);
  const int n = supersample_of(*s, supersample);
  eval::ConsistencyScore score;
  {
    LibraryCall call;
    eval::PathOptions p;
    p.frames = frames;
    p.path_frames = path_frames;
    p.size = size.value_or(0);  // 0: the scene's
    const eval::PathSetup path = eval::path_setup(s->model.features.geo, s->scene, p);
    const auto images = eval::stylerf_frames(s->model, s->scene, path.cams, code.code,
                                             s->model.features.geo.has_background, p.chunk, n);
    const auto dist = eval::lpips_distance(lpips_name ? &lpips_net(*lpips_name) : nullptr);
    score = eval::score_frames(images, path.warps, dist.get());
  }
  pyb::dict d;
  d["short_range"] = range_dict(score.short_range, lpips_name.has_value());
  d["long_range"] = range_dict(score.long_range, lpips_name.has_value());
  return d;
}

}  // namespace

void bind_eval(pyb::module_& m) {
  m.def("lpips", &lpips, pyb::arg("a"), pyb::arg("b"), pyb::arg("net") = eval::lpips_net_name(eval::kDefaultLpipsNet),
        "LPIPS (v0.1) between two H x W x 3 images of one size; net: alex or vgg.");
  m.def("consistency", &consistency, pyb::arg("model"), pyb::arg("code"), pyb::kw_only(), pyb::arg("frames") = 16,
        pyb::arg("path_frames") = 120, pyb::arg("size") = pyb::none(),
        pyb::arg("lpips") = eval::lpips_net_name(eval::kDefaultLpipsNet), pyb::arg("supersample") = pyb::none(),
        "Short- and long-range consistency of the stylised camera path, as the paper's Table 1 (`stylerf eval "
        "consistency`): the first frames of a path_frames path, at size pixels on the longer side (None: the "
        "scene's), warped by the scene's geometry; RMSE, and LPIPS with that net (None: not measured).");
}

}  // namespace stylerf::py
