#include "host/files.hpp"

#include <cerrno>
#include <csignal>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <set>
#include <signal.h>
#include <sstream>
#include <unistd.h>

#include "host/error.hpp"

namespace stylerf::host {

namespace {
// Temporary paths being written, readable from a signal handler: fixed slots of fixed-size buffers, a slot
// in use when its first byte is non-zero. Writers take the mutex; the handler only reads and unlinks
// (async-signal-safe), so at worst it sees a slot being filled and skips or unlinks a not-yet-made file.
constexpr int kSlots = 16, kPathMax = 4096;
char g_temp_paths[kSlots][kPathMax];
std::mutex g_temp_mutex;

extern "C" void remove_temps_and_reraise(int sig) {
  for (auto& p : g_temp_paths)
    if (p[0]) ::unlink(p);
  ::signal(sig, SIG_DFL);
  ::raise(sig);
}

int register_temp(const std::string& path) {
  if (path.size() + 1 > size_t(kPathMax)) return -1;
  std::lock_guard<std::mutex> lock(g_temp_mutex);
  for (int i = 0; i < kSlots; ++i)
    if (!g_temp_paths[i][0]) {
      std::memcpy(g_temp_paths[i], path.c_str(), path.size() + 1);
      return i;
    }
  return -1;  // more than kSlots concurrent writes: this one is simply not cleaned on a signal
}

void unregister_temp(int slot) {
  if (slot < 0) return;
  std::lock_guard<std::mutex> lock(g_temp_mutex);
  g_temp_paths[slot][0] = 0;
}

bool process_alive(long pid) { return pid > 0 && (::kill(pid_t(pid), 0) == 0 || errno == EPERM); }

// Folders this process already swept for dead writers' leftovers: a command writing hundreds of frames
// into one folder scans it once, not once per frame.
std::set<std::string> g_swept;
std::mutex g_swept_mutex;
void sweep_once(const std::string& path) {
  namespace fs = std::filesystem;
  const fs::path target(path);
  std::error_code ec;
  const std::string dir = fs::absolute(target.has_parent_path() ? target.parent_path() : fs::path("."), ec).string();
  {
    std::lock_guard<std::mutex> lock(g_swept_mutex);
    if (!g_swept.insert(dir).second) return;
  }
  remove_stale_temps((fs::path(dir) / "*").string());
}
}  // namespace

void install_temp_file_cleanup() {
  // Checked on every call (two sigaction queries): a handler set up later by the program keeps priority,
  // and one that is reset to the default gets ours again.
  for (int sig : {SIGINT, SIGTERM}) {
    struct sigaction old {};
    ::sigaction(sig, nullptr, &old);
    if (old.sa_handler != SIG_DFL) continue;  // the program (or a test runner) handles it: leave it
    struct sigaction sa {};
    sa.sa_handler = remove_temps_and_reraise;
    sigemptyset(&sa.sa_mask);
    ::sigaction(sig, &sa, nullptr);
  }
}

int remove_stale_temps(const std::string& path) {
  namespace fs = std::filesystem;
  const fs::path target(path);
  const fs::path dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
  const std::string name_of_target = target.filename().string();
  const bool any = name_of_target == "*";  // every target in the folder
  const std::string prefix = any ? "" : name_of_target + ".tmp-";
  std::error_code ec;
  int removed = 0;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    const size_t at = any ? name.rfind(".tmp-") : (name.rfind(prefix, 0) == 0 ? prefix.size() - 5 : std::string::npos);
    if (at == std::string::npos || at == 0) continue;
    const std::string pid = name.substr(at + 5);
    if (pid.empty() || pid.find_first_not_of("0123456789") != std::string::npos) continue;
    if (process_alive(std::stol(pid))) continue;
    std::error_code rm;
    if (fs::remove(it->path(), rm)) ++removed;
  }
  return removed;
}

void write_atomic_with(const std::string& path, const std::function<void(const std::string&)>& write) {
  namespace fs = std::filesystem;
  fs::path target(path);
  std::error_code ec;
  if (target.has_parent_path()) fs::create_directories(target.parent_path(), ec);
  std::string tmp = path + ".tmp-" + std::to_string(::getpid());
  install_temp_file_cleanup();
  sweep_once(path);  // what killed earlier writers left in this folder (once per folder and process)
  const int slot = register_temp(tmp);
  try {
    write(tmp);
  } catch (...) {
    fs::remove(tmp, ec);
    unregister_temp(slot);
    throw;
  }
  fs::rename(tmp, target, ec);
  unregister_temp(slot);
  if (ec) {
    fs::remove(tmp, ec);
    throw Error("cannot write " + path + ": rename of the temporary file failed");
  }
}

void write_file_atomic(const std::string& path, const std::string& bytes) {
  write_atomic_with(path, [&](const std::string& tmp) {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw Error("cannot open " + tmp + " for writing");
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    out.close();
    if (!out) throw Error("cannot write " + path + " (disk full?)");
  });
}

std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error("cannot open " + path + ": " + (std::filesystem::exists(path) ? "not readable" : "no such file"));
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

}  // namespace stylerf::host
