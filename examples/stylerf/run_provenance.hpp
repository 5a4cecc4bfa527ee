// What made a `stylerf run`: the command line, the OpenCL device, the build and the recipe, recorded in
// OUT/summary.json and shown on OUT/index.html so that a result can be told apart from another and redone.
#pragma once
#include <nlohmann/json.hpp>
#include <string>

namespace stylerf::cli {

// "stylerf" and argv joined by spaces, each argument quoted as a POSIX shell would need it ('...' around
// anything beyond letters, digits and -_./:=,+@%), so that the line pasted into a shell runs the same run.
std::string shell_command_line(int argc, char** argv);

// The device the run's steps use (host::choose_device of the --device spec, as each step picks it):
// {"name", "platform", "type", "driver", "compute_units"}.
nlohmann::json device_record(const std::string& spec);

// The build: {"version", "commit"} (lib/version.hpp).
nlohmann::json build_record();

}  // namespace stylerf::cli
