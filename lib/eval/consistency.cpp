#include "lib/eval/consistency.hpp"

#include <cmath>
#include <limits>
#include <string>

#include "host/error.hpp"
#include "lib/eval/finite_image.hpp"

namespace stylerf::eval {

using host::Error;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

PathWarps::Range warps_at(const std::vector<FrameGeometry>& frames, int k, const RaySpace& space,
                          const WarpOptions& opt) {
  PathWarps::Range r;
  r.k = k;
  for (size_t t = size_t(k); t < frames.size(); ++t) r.warps.push_back(correspond(frames[t], frames[t - k], space, opt));
  return r;
}

RangeScore score_range(const std::vector<io::Image>& frames, const PathWarps::Range& range,
                       const MaskedDistance* lpips) {
  RangeScore out;
  out.k = range.k;
  double rmse_sum = 0, lpips_sum = 0, valid_sum = 0;
  int counted = 0;
  for (size_t i = 0; i < range.warps.size(); ++i) {
    const Correspondence& c = range.warps[i];
    const int t = int(i) + range.k, s = int(i);
    const io::Image& ft = frames[size_t(t)];
    PairScore p;
    p.t = t;
    p.s = s;
    p.valid_fraction = c.stats.valid_fraction();
    p.stats = c.stats;
    valid_sum += p.valid_fraction;
    if (c.stats.valid == 0) {
      p.rmse = p.lpips = kNaN;
      ++out.skipped;
      out.pairs.push_back(p);
      continue;
    }
    const io::Image warped = warp_image(frames[size_t(s)], c, ft);
    p.rmse = masked_rmse(ft, warped, c.valid);
    p.lpips = lpips ? (*lpips)(ft, warped, mask_weights(c.valid)) : kNaN;
    rmse_sum += p.rmse;
    lpips_sum += p.lpips;
    ++counted;
    out.pairs.push_back(p);
  }
  out.rmse = counted ? rmse_sum / counted : kNaN;
  out.lpips = counted && lpips ? lpips_sum / counted : kNaN;
  out.valid_fraction = range.warps.empty() ? 0.0 : valid_sum / double(range.warps.size());
  return out;
}

nlohmann::json number(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

nlohmann::json range_json(const RangeScore& r) {
  nlohmann::json pairs = nlohmann::json::array();
  for (const auto& p : r.pairs)
    pairs.push_back({{"t", p.t},
                     {"s", p.s},
                     {"rmse", number(p.rmse)},
                     {"lpips", number(p.lpips)},
                     {"valid_fraction", p.valid_fraction},
                     {"valid_pixels", p.stats.valid},
                     {"left_out", {{"background", p.stats.background},
                                   {"no_depth", p.stats.no_depth},
                                   {"off_image", p.stats.off_image},
                                   {"occluded", p.stats.occluded}}}});
  return {{"k", r.k},           {"rmse", number(r.rmse)},       {"lpips", number(r.lpips)},
          {"skipped", r.skipped}, {"valid_fraction", r.valid_fraction}, {"pairs", pairs}};
}

}  // namespace

PathWarps path_warps(const std::vector<FrameGeometry>& frames, const RaySpace& space, const ConsistencyOptions& opt) {
  if (opt.short_range < 1 || opt.long_range < 1)
    throw Error("consistency: the ranges must be >= 1 frame (got " + std::to_string(opt.short_range) + " and " +
                std::to_string(opt.long_range) + ")");
  if (int(frames.size()) <= opt.long_range)
    throw Error("consistency: " + std::to_string(frames.size()) + " frames leave no pair at the long range of " +
                std::to_string(opt.long_range) + " (need at least " + std::to_string(opt.long_range + 1) + ")");
  PathWarps w;
  w.frames = int(frames.size());
  w.short_range = warps_at(frames, opt.short_range, space, opt.warp);
  w.long_range = warps_at(frames, opt.long_range, space, opt.warp);
  return w;
}

ConsistencyScore score_frames(const std::vector<io::Image>& frames, const PathWarps& warps,
                              const MaskedDistance* lpips) {
  if (int(frames.size()) != warps.frames)
    throw Error("consistency: " + std::to_string(frames.size()) + " frames for warps of " +
                std::to_string(warps.frames));
  if (warps.short_range.warps.empty()) throw Error("consistency: no warps (make them with path_warps)");
  const Correspondence& c = warps.short_range.warps.front();
  for (size_t i = 0; i < frames.size(); ++i)
    if (frames[i].width != c.width || frames[i].height != c.height)
      throw Error("consistency: frame " + std::to_string(i) + " is " + std::to_string(frames[i].width) + "x" +
                  std::to_string(frames[i].height) + ", the geometry's frames " + std::to_string(c.width) + "x" +
                  std::to_string(c.height));
  for (size_t i = 0; i < frames.size(); ++i)
    if (const std::string bad = non_finite_at(frames[i]); !bad.empty())
      throw Error("consistency: frame " + std::to_string(i) + " has " + bad + " (a failed render cannot be scored)");
  ConsistencyScore s;
  s.short_range = score_range(frames, warps.short_range, lpips);
  s.long_range = score_range(frames, warps.long_range, lpips);
  return s;
}

nlohmann::json ConsistencyScore::to_json() const {
  return {{"short", range_json(short_range)}, {"long", range_json(long_range)}};
}

namespace {
double number_or_nan(const nlohmann::json& v) { return v.is_null() ? std::nan("") : v.get<double>(); }

RangeScore range_from_json(const nlohmann::json& j) {
  RangeScore r;
  r.k = j.at("k").get<int>();
  r.rmse = number_or_nan(j.at("rmse"));
  r.lpips = number_or_nan(j.at("lpips"));
  r.skipped = j.at("skipped").get<int>();
  r.valid_fraction = j.at("valid_fraction").get<double>();
  for (const auto& pj : j.at("pairs")) {
    PairScore p;
    p.t = pj.at("t").get<int>();
    p.s = pj.at("s").get<int>();
    p.rmse = number_or_nan(pj.at("rmse"));
    p.lpips = number_or_nan(pj.at("lpips"));
    p.valid_fraction = pj.at("valid_fraction").get<double>();
    p.stats.valid = pj.at("valid_pixels").get<int64_t>();
    const auto& out = pj.at("left_out");
    p.stats.background = out.at("background").get<int64_t>();
    p.stats.no_depth = out.at("no_depth").get<int64_t>();
    p.stats.off_image = out.at("off_image").get<int64_t>();
    p.stats.occluded = out.at("occluded").get<int64_t>();
    r.pairs.push_back(p);
  }
  return r;
}
}  // namespace

ConsistencyScore ConsistencyScore::from_json(const nlohmann::json& j) {
  ConsistencyScore s;
  s.short_range = range_from_json(j.at("short"));
  s.long_range = range_from_json(j.at("long"));
  return s;
}

}  // namespace stylerf::eval
