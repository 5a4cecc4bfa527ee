// stylerf: train and render StyleRF models on OpenCL devices. `stylerf help` lists the subcommands.
#include <sys/resource.h>

#include <cstring>
#include <exception>
#include <iostream>

#include "bench/timing.hpp"
#include "examples/stylerf/cli_checks.hpp"
#include "examples/stylerf/commands.hpp"
#include "host/error.hpp"
#include "host/runtime.hpp"

namespace stylerf::cli {

std::vector<Command>& commands() {
  static std::vector<Command> list;
  return list;
}

Register::Register(std::string name, std::string summary, CommandFn fn) {
  commands().push_back({std::move(name), std::move(summary), std::move(fn)});
}

double peak_rss_mb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_maxrss) / 1024.0;  // Linux reports kilobytes
}

void init_runtime(const std::string& device_spec, bool profile) {
  auto& rt = host::Runtime::init(device_spec);
  if (profile) rt.set_profiling(true);
}

}  // namespace stylerf::cli

namespace {
// STYLERF_PROFILE=1: the whole command's device time per kernel, longest first, on stderr (what a frame or a
// step spends where, without a bench).
void print_profile_report() {
  if (!stylerf::host::Runtime::initialised() || !stylerf::host::Runtime::instance().profiling()) return;
  stylerf::bench::print_top_kernels(25, "device time per kernel over the whole command", stderr);
}

void usage() {
  std::cout << "usage: stylerf <command> [options]   (stylerf <command> --help for its options)\n\ncommands:\n";
  for (const auto& c : stylerf::cli::commands()) std::cout << "  " << c.name << std::string(16 - std::min<size_t>(15, c.name.size()), ' ') << c.summary << "\n";
}
}  // namespace

int main(int argc, char** argv) {
  if (argc < 2 || !std::strcmp(argv[1], "help") || !std::strcmp(argv[1], "--help") || !std::strcmp(argv[1], "-h")) {
    usage();
    return argc < 2 ? 2 : 0;
  }
  for (const auto& c : stylerf::cli::commands()) {
    if (c.name == argv[1]) {
      int rc = 1;
      try {
        rc = c.run(argc - 1, argv + 1);
        print_profile_report();
        stylerf::host::Runtime::shutdown();
      } catch (const std::exception& e) {
        // A library setting's error names its config field; the user typed a flag.
        const auto* setting = dynamic_cast<const stylerf::host::SettingError*>(&e);
        std::cerr << "stylerf " << c.name << ": error: "
                  << (setting ? stylerf::cli::flag_for_field(setting->field()) + " " + setting->problem() : e.what())
                  << std::endl;
        try {
          stylerf::host::Runtime::shutdown();
        } catch (const std::exception&) {
        }
      }
      return rc;
    }
  }
  std::cerr << "stylerf: unknown command '" << argv[1] << "'\n";
  usage();
  return 2;
}
