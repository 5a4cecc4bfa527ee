// Runs the built `stylerf` tool as a user would (through a shell), for the suites that test commands end to
// end. The suite must be compiled with STYLERF_CLI (CMakeLists.txt sets it for those suites).
#pragma once
#include <fstream>
#include <iostream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <string>
#include <sys/wait.h>

#include "tests/small_scene.hpp"

namespace stylerf::testing {

struct CliRun {
  int code = 0;  // exit status; -1 when killed by a signal
  std::string output;
};

inline CliRun run_cli(const std::string& args) {
  const std::string log = (small_work_dir() / "cli.log").string();
  const std::string cmd = std::string("'") + STYLERF_CLI + "' " + args + " > '" + log + "' 2>&1";
  const int status = std::system(cmd.c_str());
  std::ifstream f(log);
  CliRun r;
  r.output.assign(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  // Under Oclgrind (scripts/oclgrind.sh) the tool runs on the simulator too (its LD_PRELOAD is inherited)
  // and reports to the tool's stderr, captured above: pass an output holding a report on to this process's
  // stderr, where the script counts reports.
  for (const char* report : {"Invalid read", "Invalid write", "data race", "Uninitialised", "Uninitialized",
                             "OpenCL runtime error", "OCLGRIND FATAL", "divergence"})
    if (r.output.find(report) != std::string::npos) {
      std::cerr << "---- stylerf " << args << " (exit " << r.code << "):\n" << r.output << std::endl;
      break;
    }
  return r;
}

// A JSON file the tool wrote.
inline nlohmann::json read_json(const std::filesystem::path& p) {
  std::ifstream f(p);
  return nlohmann::json::parse(f);
}

}  // namespace stylerf::testing
