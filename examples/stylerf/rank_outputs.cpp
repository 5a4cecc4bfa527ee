#include "examples/stylerf/rank_outputs.hpp"

#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "host/dist.hpp"
#include "host/error.hpp"
#include "host/files.hpp"

namespace stylerf::cli {

namespace fs = std::filesystem;

namespace {

void put_u64(std::string& s, uint64_t v) { s.append(reinterpret_cast<const char*>(&v), sizeof v); }

uint64_t get_u64(const std::string& s, size_t& at) {
  if (at + sizeof(uint64_t) > s.size()) throw host::Error("rank outputs: a truncated message");
  uint64_t v = 0;
  std::memcpy(&v, s.data() + at, sizeof v);
  at += sizeof v;
  return v;
}

std::string get_bytes(const std::string& s, size_t& at, uint64_t n) {
  if (at + n > s.size()) throw host::Error("rank outputs: a truncated message");
  std::string out = s.substr(at, size_t(n));
  at += size_t(n);
  return out;
}

// Every file under dir as (relative path, bytes) pairs, one message.
std::string pack_folder(const std::string& dir) {
  std::string msg;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    if (!e.is_regular_file()) continue;
    const std::string rel = fs::relative(e.path(), dir).string();
    std::ifstream f(e.path(), std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
    put_u64(msg, rel.size());
    msg += rel;
    put_u64(msg, bytes.size());
    msg += bytes;
  }
  return msg;
}

}  // namespace

bool my_view(size_t i) {
  auto& d = host::Dist::world();
  d.alive();  // asked as the rank reaches each view: its sign of life while the others wait at the gather
  return int(i % size_t(d.size())) == d.rank();
}

std::string rank_output_dir(const std::string& out) {
  const auto& d = host::Dist::world();
  if (d.root()) return out;
  const fs::path p = fs::temp_directory_path() /
                     ("stylerf-rank" + std::to_string(d.rank()) + "-" + std::to_string(::getpid()));
  fs::remove_all(p);
  fs::create_directories(p);
  return p.string();
}

void collect_rank_outputs(const std::string& rank_dir, const std::string& out) {
  auto& d = host::Dist::world();
  if (d.size() == 1) return;
  const auto all = d.gather(d.root() ? std::string() : pack_folder(rank_dir));
  if (!d.root()) {
    std::error_code ec;
    fs::remove_all(rank_dir, ec);
    return;
  }
  for (size_t r = 1; r < all.size(); ++r) {
    const std::string& msg = all[r];
    for (size_t at = 0; at < msg.size();) {
      const std::string rel = get_bytes(msg, at, get_u64(msg, at));
      const std::string bytes = get_bytes(msg, at, get_u64(msg, at));
      if (rel.empty() || fs::path(rel).is_absolute() || rel.find("..") != std::string::npos)
        throw host::Error("rank outputs: rank " + std::to_string(r) + " sent a file outside its folder: " + rel);
      const fs::path to = fs::path(out) / rel;
      fs::create_directories(to.parent_path());
      host::write_file_atomic(to.string(), bytes);
    }
  }
}

nlohmann::json gather_view_rows(const nlohmann::json& mine) {
  auto& d = host::Dist::world();
  if (d.size() == 1) return mine;
  nlohmann::json out = nlohmann::json::array();
  for (const auto& text : d.gather(mine.dump()))
    for (auto& row : nlohmann::json::parse(text)) out.push_back(std::move(row));
  std::sort(out.begin(), out.end(), [](const auto& x, const auto& y) { return x["view"] < y["view"]; });
  return out;
}

}  // namespace stylerf::cli
