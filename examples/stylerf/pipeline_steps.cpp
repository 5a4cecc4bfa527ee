#include "examples/stylerf/pipeline_steps.hpp"


#include <algorithm>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <sstream>

#include "examples/stylerf/split_commands.hpp"
#include "host/error.hpp"
#include "host/files.hpp"
#include "lib/io/process.hpp"
#include "lib/io/sha256.hpp"

namespace fs = std::filesystem;

namespace stylerf::cli {

using host::Error;

std::string folder_fingerprint(const std::string& dir) {
  std::vector<std::string> rows;
  std::error_code ec;
  for (auto it = fs::recursive_directory_iterator(dir, ec); !ec && it != fs::recursive_directory_iterator();
       it.increment(ec)) {
    if (!it->is_regular_file()) continue;
    const auto mtime = it->last_write_time().time_since_epoch().count();
    rows.push_back(fs::relative(it->path(), dir).string() + " " + std::to_string(it->file_size()) + " " +
                   std::to_string(mtime));
  }
  if (ec) throw Error("cannot list " + dir + ": " + ec.message());
  std::sort(rows.begin(), rows.end());
  std::string all;
  for (const auto& r : rows) all += r + "\n";
  return io::sha256_hex(all);
}

namespace {

const char* kRecord = "steps.json";

// Runs self with args, its output shown line by line and kept in `log_path`. Returns the child's exit status
// (128 + signal when killed); peak_rss_mb: the child's peak resident memory.
int run_child(const std::string& self, const std::vector<std::string>& args, const std::string& log_path,
              double& peak_rss_mb) {
  const io::ProcessResult r =
      io::run_process(self, args, [](const std::string& line) { std::cout << line << "\n" << std::flush; }, log_path);
  peak_rss_mb = r.peak_rss_mb;
  return r.status;
}

}  // namespace

PipelineSteps::PipelineSteps(std::string out, std::string self) : out_(std::move(out)), self_(std::move(self)) {
  fs::create_directories(fs::path(out_) / "logs");
  const fs::path rec = fs::path(out_) / kRecord;
  record_ = nlohmann::json::object();
  if (fs::exists(rec)) {
    try {
      std::ifstream f(rec);
      record_ = nlohmann::json::parse(f);
    } catch (const std::exception& e) {
      std::cout << "note: " << rec.string() << " is unreadable (" << e.what() << "); every step runs again\n";
      record_ = nlohmann::json::object();
    }
  }
}

void PipelineSteps::split_over_ranks(int ranks, std::vector<std::string> launcher) {
  ranks_ = ranks;
  launcher_ = std::move(launcher);
}

PipelineSteps::Result PipelineSteps::run(const std::string& name, const std::vector<std::string>& args,
                                         const std::string& output, const std::string& extra_key) {
  const bool split = ranks_ > 1 && !args.empty() && splits_over_ranks(args[0], args.size() > 1 ? args[1] : "");
  std::string joined;
  for (const auto& a : args) joined += a + '\x1f';
  // N ranks train differently (N styles or patches a step by default): the count is part of the step.
  if (split) joined += "ranks=" + std::to_string(ranks_) + '\x1f';
  Result r;
  r.key = io::sha256_hex(joined + '\x1e' + extra_key);
  const auto& prev = record_.value(name, nlohmann::json::object());
  if (prev.value("key", "") == r.key && fs::exists(output)) {
    r.skipped = true;
    r.seconds = prev.value("seconds", 0.0);
    std::cout << "== " << name << ": done in an earlier run (" << std::fixed << std::setprecision(0) << r.seconds
              << " s), kept: " << output << std::endl;
    return r;
  }
  std::string program = self_, shown = "stylerf";
  std::vector<std::string> full = args;
  if (split) {
    program = launcher_.front();
    full.assign(launcher_.begin() + 1, launcher_.end());
    for (const auto& a : {std::string("-np"), std::to_string(ranks_), self_}) full.push_back(a);
    full.insert(full.end(), args.begin(), args.end());
    shown.clear();
    for (const auto& a : launcher_) shown += (shown.empty() ? "" : " ") + a;
    shown += " -np " + std::to_string(ranks_) + " stylerf";
  }
  for (const auto& a : args) shown += " " + a;
  std::cout << "== " << name << ": " << shown << std::endl;
  const std::string log = (fs::path(out_) / "logs" / (name + ".log")).string();
  const auto t0 = std::chrono::steady_clock::now();
  double rss = 0;
  const int rc = run_child(program, full, log, rss);
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (rc != 0)
    throw Error("step '" + name + "' failed (exit status " + std::to_string(rc) + "); its output is in " + log);
  record_[name] = {{"key", r.key}, {"seconds", r.seconds}, {"peak_rss_mb", rss}};
  host::write_file_atomic((fs::path(out_) / kRecord).string(), record_.dump(2) + "\n");
  return r;
}

}  // namespace stylerf::cli
