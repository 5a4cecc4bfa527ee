#include "lib/io/process.hpp"

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iostream>
#include <sstream>

#include "host/error.hpp"

namespace stylerf::io {

using host::Error;

std::string find_program(const std::string& name) {
  if (name.empty()) return "";
  if (name.find('/') != std::string::npos) return access(name.c_str(), X_OK) == 0 ? name : "";
  const char* path = std::getenv("PATH");
  std::stringstream dirs(path ? path : "/usr/local/bin:/usr/bin:/bin");
  std::string dir;
  while (std::getline(dirs, dir, ':')) {
    const std::string full = (dir.empty() ? "." : dir) + "/" + name;
    if (access(full.c_str(), X_OK) == 0) return full;
  }
  return "";
}

ProcessResult run_process(const std::string& program, const std::vector<std::string>& args,
                          const std::function<void(const std::string& line)>& on_line, const std::string& log_path) {
  int fds[2];
  if (pipe(fds) != 0) throw Error("pipe() failed: " + std::string(std::strerror(errno)));
  std::cout.flush();
  std::cerr.flush();
  const pid_t pid = fork();
  if (pid < 0) {
    close(fds[0]);
    close(fds[1]);
    throw Error("fork() failed: " + std::string(std::strerror(errno)));
  }
  if (pid == 0) {
    dup2(fds[1], 1);
    dup2(fds[1], 2);
    close(fds[0]);
    close(fds[1]);
    std::vector<char*> argv;
    argv.push_back(const_cast<char*>(program.c_str()));
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    execvp(program.c_str(), argv.data());
    std::fprintf(stderr, "cannot run %s: %s\n", program.c_str(), std::strerror(errno));
    _exit(127);
  }
  close(fds[1]);
  std::ofstream log;
  if (!log_path.empty()) log.open(log_path);
  std::string pending;
  bool after_cr = false;  // a '\n' right after a '\r' ends no second line
  char buf[4096];
  ssize_t n;
  while ((n = read(fds[0], buf, sizeof buf)) > 0 || (n < 0 && errno == EINTR)) {
    if (n <= 0) continue;
    if (log.is_open()) log.write(buf, n).flush();
    // Progress bars end some lines with '\r' only: '\r', '\n' and "\r\n" each end one line.
    for (ssize_t i = 0; i < n; ++i) {
      const char c = buf[i];
      if (c == '\n' && after_cr) {
        after_cr = false;
        continue;
      }
      after_cr = c == '\r';
      if (c == '\n' || c == '\r') {
        if (on_line) on_line(pending);
        pending.clear();
      } else {
        pending.push_back(c);
      }
    }
  }
  close(fds[0]);
  if (!pending.empty() && on_line) on_line(pending);
  int status = 0;
  rusage usage{};
  while (wait4(pid, &status, 0, &usage) < 0 && errno == EINTR) {
  }
  ProcessResult r;
  r.peak_rss_mb = double(usage.ru_maxrss) / 1024.0;  // Linux reports kilobytes
  r.status = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + (WIFSIGNALED(status) ? WTERMSIG(status) : 0);
  return r;
}

}  // namespace stylerf::io
