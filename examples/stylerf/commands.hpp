// The `stylerf` command line: each subcommand lives in its own cmd_*.cpp and registers itself here.
#pragma once
#include <chrono>
#include <functional>
#include <string>
#include <vector>

namespace stylerf::cli {

// A subcommand gets the arguments after its name (args[0] is "stylerf <name>") and returns the exit code.
using CommandFn = std::function<int(int argc, char** argv)>;

struct Command {
  std::string name;  // its group, summary and examples are in command_index.cpp
  CommandFn run;
};

std::vector<Command>& commands();

struct Register {
  Register(std::string name, CommandFn fn);
};

// Common options every subcommand accepts: --device SPEC (also STYLERF_DEVICE), --timing (kernel times).
// Initialises the OpenCL runtime on the chosen device.
void init_runtime(const std::string& device_spec, bool timing);

// This process's peak resident memory so far, in MB (getrusage; the training commands print it at the end).
double peak_rss_mb();

// Wall seconds since t (the commands' timings).
inline double seconds_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

}  // namespace stylerf::cli
