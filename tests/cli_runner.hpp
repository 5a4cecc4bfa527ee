// Runs the built `stylerf` tool as a user would (through a shell), for the suites that test commands end to
// end. The suite must be compiled with STYLERF_CLI (CMakeLists.txt sets it for those suites).
#pragma once
#include <cstdlib>
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
  // Under Oclgrind (scripts/oclgrind.sh sets the variable) the tool runs on the simulator too and reports to
  // its own stderr, captured above: pass that output on to this process's stderr, the log the script reads.
  if (const char* fwd = std::getenv("STYLERF_TEST_FORWARD_CLI_OUTPUT"); fwd && std::string(fwd) == "1")
    std::cerr << "---- stylerf " << args << " (exit " << r.code << "):\n" << r.output << std::endl;
  return r;
}

// A JSON file the tool wrote.
inline nlohmann::json read_json(const std::filesystem::path& p) {
  std::ifstream f(p);
  return nlohmann::json::parse(f);
}

}  // namespace stylerf::testing
