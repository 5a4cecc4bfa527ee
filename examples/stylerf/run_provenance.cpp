#include "examples/stylerf/run_provenance.hpp"

#include "host/device.hpp"
#include "lib/version.hpp"

namespace stylerf::cli {

namespace {
std::string shell_quoted(const std::string& arg) {
  const bool plain = !arg.empty() && arg.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ"
                                                           "0123456789-_./:=,+@%") == std::string::npos;
  if (plain) return arg;
  std::string q = "'";
  for (char c : arg) q += c == '\'' ? std::string("'\\''") : std::string(1, c);  // close, escaped ', reopen
  return q + "'";
}
}  // namespace

std::string shell_command_line(int argc, char** argv) {
  std::string line = "stylerf";
  for (int i = 0; i < argc; ++i) line += " " + shell_quoted(argv[i]);
  return line;
}

nlohmann::json device_record(const std::string& spec) {
  const host::DeviceInfo d = host::choose_device(spec);
  return {{"name", d.name},
          {"platform", d.platform_name},
          {"type", d.type_name()},
          {"driver", d.driver},
          {"compute_units", d.compute_units}};
}

nlohmann::json build_record() { return {{"version", stylerf::version()}, {"commit", stylerf::git_commit()}}; }

}  // namespace stylerf::cli
