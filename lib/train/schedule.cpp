#include "lib/train/schedule.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "host/error.hpp"

namespace stylerf::train {

using host::Error;

static void check_sorted(const std::vector<int>& v, const char* field) {
  for (size_t i = 0; i < v.size(); ++i) {
    if (v[i] < 1) throw host::SettingError(field, "has iteration " + std::to_string(v[i]) + " (< 1)");
    if (i > 0 && v[i] <= v[i - 1]) throw host::SettingError(field, "must be strictly increasing");
  }
}

void Schedule::validate() const {
  if (iters < 1) throw host::SettingError("iters", "must be >= 1, got " + std::to_string(iters));
  if (voxels_init < 8) throw host::SettingError("voxels_init", "must be >= 8, got " + std::to_string(voxels_init));
  if (voxels_final < 8) throw host::SettingError("voxels_final", "must be >= 8, got " + std::to_string(voxels_final));
  if (!(lr_decay_ratio > 0.0f && lr_decay_ratio <= 1.0f))
    throw host::SettingError("lr_decay_ratio", "must be in (0, 1], got " + std::to_string(lr_decay_ratio));
  check_sorted(upsample_at, "upsample_at");
  check_sorted(mask_at, "mask_at");
}

std::vector<int64_t> Schedule::voxel_list() const {
  const size_t n = upsample_at.size();
  std::vector<int64_t> out;
  const double a = std::log(double(voxels_init)), b = std::log(double(voxels_final));
  for (size_t i = 1; i <= n; ++i) out.push_back(std::llround(std::exp(a + (b - a) * double(i) / double(n))));
  return out;
}

int64_t Schedule::voxels_after(int done) const {
  const auto list = voxel_list();
  int64_t v = voxels_init;
  for (size_t i = 0; i < upsample_at.size(); ++i)
    if (upsample_at[i] <= done) v = list[i];
  return v;
}

float Schedule::lr_scale(int step) const {
  int since = 0;  // the step count at which the rate was last reset
  if (lr_reset_on_upsample)
    for (int u : upsample_at)
      if (u <= step - 1) since = u;
  return static_cast<float>(std::pow(double(lr_decay_ratio), double(step - 1 - since) / double(iters)));
}

float Schedule::reg_scale(int step) const {
  return static_cast<float>(std::pow(double(lr_decay_ratio), double(step - 1) / double(iters)));
}

bool Schedule::upsample_at_step(int done) const {
  return std::find(upsample_at.begin(), upsample_at.end(), done) != upsample_at.end();
}

bool Schedule::mask_at_step(int done) const { return std::find(mask_at.begin(), mask_at.end(), done) != mask_at.end(); }

Schedule Schedule::fitted(int new_iters, int min_first) const {
  if (new_iters < 1) throw Error("schedule: fitted run must have >= 1 iteration, got " + std::to_string(new_iters));
  Schedule s = *this;
  s.iters = new_iters;
  int first = iters;
  if (!upsample_at.empty()) first = std::min(first, upsample_at.front());
  if (!mask_at.empty()) first = std::min(first, mask_at.front());
  int last = 0;
  if (!upsample_at.empty()) last = std::max(last, upsample_at.back());
  if (!mask_at.empty()) last = std::max(last, mask_at.back());
  // Keep the events where they are when they fit in the first 80% of the run (TensoRF's lego events end at
  // 5500 of 30000; a 6000-step run keeps them); otherwise pull them in just enough. Never so far that the
  // first event comes before min_first.
  double f = last > 0 ? std::min(1.0, 0.8 * double(new_iters) / double(last)) : 1.0;
  f = std::max(f, double(min_first) / double(std::max(first, 1)));
  auto scale = [&](const std::vector<int>& v) {
    std::vector<int> out;
    for (int e : v) out.push_back(std::max(int(std::lround(e * f)), out.empty() ? 1 : out.back() + 1));
    return out;
  };
  s.upsample_at = scale(upsample_at);
  s.mask_at = scale(mask_at);
  return s;
}

std::string Schedule::describe() const {
  std::ostringstream o;
  const auto list = voxel_list();
  o << "grid " << std::llround(std::cbrt(double(voxels_init))) << "^3";
  if (upsample_at.empty()) o << " (no upsampling)";
  for (size_t i = 0; i < upsample_at.size(); ++i)
    o << (i ? ", " : "; upsample at ") << upsample_at[i] << " -> " << std::llround(std::cbrt(double(list[i]))) << "^3";
  o << "; alpha mask at";
  if (mask_at.empty()) o << " (never)";
  for (int m : mask_at) o << ' ' << m;
  o << "; lr x" << lr_decay_ratio << " over " << iters << " iterations"
    << (lr_reset_on_upsample ? " (reset at each upsample, as TensoRF)" : "");
  return o.str();
}

std::vector<int> parse_int_list(const std::string& s, const std::string& flag) {
  std::vector<int> out;
  std::string item;
  std::istringstream in(s);
  while (std::getline(in, item, ',')) {
    if (item.empty()) continue;
    size_t used = 0;
    int v = 0;
    try {
      v = std::stoi(item, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != item.size()) throw Error(flag + ": '" + item + "' is not an integer (expected e.g. 2000,3000)");
    out.push_back(v);
  }
  return out;
}

}  // namespace stylerf::train
