#include "examples/stylerf/cli_checks.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>
#include <unistd.h>

#include "host/error.hpp"
#include "host/files.hpp"

namespace stylerf::cli {

using host::Error;
namespace fs = std::filesystem;

namespace {
std::string str(double v) {
  std::ostringstream o;
  o << v;
  return o.str();
}
}  // namespace

void check_range(const std::string& option, double v, double lo, double hi) {
  if (!std::isfinite(v) || v < lo || v > hi)
    throw Error(option + " must be a number in [" + str(lo) + ", " + str(hi) + "] (got " + str(v) + ")");
}

void check_int_range(const std::string& option, long long v, long long lo, long long hi) {
  if (v < lo || v > hi)
    throw Error(option + " must be an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "] (got " +
                std::to_string(v) + ")");
}

void check_checkpoint_output(const std::string& out, bool resume, bool force) {
  if (out.empty()) throw Error("-o CKPT is required (the checkpoint to write)");
  std::error_code ec;
  const fs::path target(out);
  if (fs::is_directory(target, ec)) throw Error("-o " + out + " is a folder; give a checkpoint file name inside it");
  const bool exists = fs::exists(target, ec);
  if (exists && !resume && !force)
    throw Error("-o " + out + " exists: pass --resume to continue it or --force to overwrite it");
  if (!exists && resume) throw Error("--resume: " + out + " does not exist");
  const fs::path dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
  if (fs::exists(dir, ec) && !fs::is_directory(dir, ec))
    throw Error("-o " + out + ": " + dir.string() + " is a file, not a folder");
  fs::create_directories(dir, ec);
  if (ec) throw Error("-o " + out + ": cannot create the folder " + dir.string() + " (" + ec.message() + ")");
  const fs::path probe = dir / (".stylerf-write-probe-" + std::to_string(::getpid()));
  {
    std::ofstream f(probe);
    if (!f) throw Error("-o " + out + ": the folder " + dir.string() + " is not writable");
  }
  fs::remove(probe, ec);
  if (const int n = host::remove_stale_temps(out))
    std::cout << "removed " << n << " temporary file(s) an interrupted earlier run left beside " << out << "\n";
}

std::string flag_for_field(const std::string& field) {
  static const std::map<std::string, std::string> own = {
      {"lr_decay_ratio", "--lr-decay"}, {"dst_bias", "--dst"}, {"warm_start", "--warm-start"},
      {"holdout_styles", "--holdout-styles"}, {"time_budget_s", "--minutes"},
      {"voxels_init", "--init-voxels"}, {"voxels_final", "--final-voxels"}};
  if (const auto it = own.find(field); it != own.end()) return it->second;
  std::string flag = "--" + field;
  std::replace(flag.begin(), flag.end(), '_', '-');
  return flag;
}

}  // namespace stylerf::cli
