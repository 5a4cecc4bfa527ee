// Child processes: run a program with arguments, its stdout and stderr merged and handed over line by line
// (shown live, kept in a log, parsed for progress), then its exit status and peak memory. Used by
// `stylerf run` (each pipeline step is a stylerf child) and by the COLMAP import.
#pragma once
#include <functional>
#include <string>
#include <vector>

namespace stylerf::io {

struct ProcessResult {
  int status = 0;           // the exit code, or 128 + the signal that killed it (127: could not be run)
  double peak_rss_mb = 0;   // the child's peak resident memory
};

// Runs `program` (a path, or a name looked up on PATH) with `args`. Every line it prints, stdout and stderr
// merged, goes to on_line (without its newline; a last line without one too) and, when log_path is not
// empty, to that file as it came. Throws host::Error only when the process cannot be started (fork or
// pipe failing); a program that is not found exits with 127 and says so on its output.
ProcessResult run_process(const std::string& program, const std::vector<std::string>& args,
                          const std::function<void(const std::string& line)>& on_line,
                          const std::string& log_path = "");

// The full path of `name` on PATH (or name itself when it contains a '/' and is executable); "" when none.
std::string find_program(const std::string& name);

}  // namespace stylerf::io
