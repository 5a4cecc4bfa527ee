// stylerf: train and render StyleRF models on OpenCL devices. `stylerf help` lists the commands by workflow.
#include <sys/resource.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <iostream>

#include "bench/timing.hpp"
#include "examples/stylerf/cli_checks.hpp"
#include "examples/stylerf/command_index.hpp"
#include "examples/stylerf/commands.hpp"
#include "examples/stylerf/split_commands.hpp"
#include "host/device.hpp"
#include "host/dist.hpp"
#include "host/error.hpp"
#include "host/runtime.hpp"
#include "lib/version.hpp"

namespace stylerf::cli {

std::vector<Command>& commands() {
  static std::vector<Command> list;
  return list;
}

Register::Register(std::string name, CommandFn fn) { commands().push_back({std::move(name), std::move(fn)}); }

double peak_rss_mb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_maxrss) / 1024.0;  // Linux reports kilobytes
}

void init_runtime(const std::string& device_spec, bool timing) {
  // Several ranks and no --device: one device each, by the rank's place on its machine.
  std::string spec = device_spec;
  const auto& dist = host::Dist::world();
  if (spec.empty() && dist.size() > 1 && !std::getenv("STYLERF_DEVICE"))
    spec = std::to_string(dist.local_rank() % std::max<size_t>(1, host::list_devices().size()));
  auto& rt = host::Runtime::init(spec);
  if (dist.size() > 1) {
    const auto names = host::Dist::world().gather("rank " + std::to_string(dist.rank()) + ": " + rt.device().name);
    for (const auto& n : names) std::cout << n << "\n";
  }
  if (timing) rt.set_profiling(true);
}

}  // namespace stylerf::cli

namespace {
namespace cli = stylerf::cli;

// STYLERF_PROFILE=1: the whole command's device time per kernel, longest first, on stderr (what a frame or a
// step spends where, without a bench).
void print_profile_report() {
  if (!stylerf::host::Runtime::initialised() || !stylerf::host::Runtime::instance().profiling()) return;
  stylerf::bench::print_top_kernels(25, "device time per kernel over the whole command", stderr);
}

const cli::Command* find_command(const std::string& name) {
  for (const auto& c : cli::commands())
    if (c.name == name) return &c;
  return nullptr;
}

// `stylerf help`: the commands group by group in workflow order, each with its summary and first example.
void usage(std::ostream& os) {
  os << "usage: stylerf <command> [options]\n"
     << "       stylerf <command> --help   the command's options and examples\n"
     << "       stylerf --version          version, git commit and OpenCL devices\n";
  for (const std::string& group : cli::workflow_groups()) {
    os << "\n" << group << ":\n";
    for (const auto& c : cli::command_index()) {
      if (c.group != group || c.name.find(' ') != std::string::npos) continue;
      os << "  " << c.name << std::string(16 - std::min<size_t>(15, c.name.size()), ' ') << c.summary << "\n"
         << std::string(18, ' ') << c.examples.front() << "\n";
    }
  }
  os << "\nExamples:\n  stylerf train-density --help\n  stylerf --version\n";
}

// `stylerf --version`: what was built, and where it can run.
int print_version() {
  std::cout << "stylerf " << stylerf::version() << " (commit " << stylerf::git_commit() << ")\n"
            << "MPI: " << (stylerf::host::Dist::built_with_mpi() ? "yes (mpirun -np N stylerf ...)" : "no") << "\n"
            << "OpenCL devices:\n";
  try {
    const auto devices = stylerf::host::list_devices();
    if (devices.empty()) std::cout << "  none found\n";
    for (const auto& d : devices) std::cout << "  " << d.describe() << "\n";
  } catch (const std::exception& e) {
    std::cout << "  none usable: " << e.what() << "\n";
  }
  return 0;
}

// Every registered command must have its line in command_index.cpp (group, summary, examples): a command
// added without one is a programming error, reported before anything runs.
bool index_complete() {
  bool ok = true;
  for (const auto& c : cli::commands())
    if (!cli::find_command_info(c.name)) {
      std::cerr << "stylerf: internal error: command '" << c.name << "' has no entry in command_index.cpp\n";
      ok = false;
    }
  return ok;
}

// A command that does not split its work over MPI ranks (split_commands.hpp), started on several, would do
// the same work on each and write the same files at once: it is refused (by rank 0; the others leave quietly).
bool runs_over_ranks(const std::string& command, const std::string& sub) {
  auto& dist = stylerf::host::Dist::world();
  if (dist.size() == 1 || cli::splits_over_ranks(command, sub)) return true;
  const std::string name = command == "eval" && !sub.empty() ? command + " " + sub : command;
  if (dist.root())
    std::cerr << "stylerf " << name << ": error: runs on one rank only, and this job has " << dist.size()
              << " (mpirun -np 1, or no mpirun); the training stages, stylize, render, eval style and eval table "
                 "split their work over ranks"
              << (command == "run" ? "; `stylerf run --ranks N` starts those under mpirun itself" : "") << "\n";
  dist.finalize();
  return false;
}

int run_command(const cli::Command& c, int argc, char** argv) {
  int rc = 1;
  try {
    rc = c.run(argc, argv);
    print_profile_report();
    stylerf::host::Runtime::shutdown();
  } catch (const std::exception& e) {
    // A library setting's error names its config field; the user typed a flag.
    const auto* setting = dynamic_cast<const stylerf::host::SettingError*>(&e);
    auto& dist = stylerf::host::Dist::world();
    std::cerr << "stylerf " << c.name << ": "
              << (dist.size() > 1 ? "rank " + std::to_string(dist.rank()) + " of " + std::to_string(dist.size()) + ": "
                                  : std::string())
              << "error: " << (setting ? cli::flag_for_field(setting->field()) + " " + setting->problem() : e.what())
              << std::endl;
    // The other ranks may be waiting for this one in a collective: end the whole job rather than hang it.
    if (dist.size() > 1) dist.abort(1);
    try {
      stylerf::host::Runtime::shutdown();
    } catch (const std::exception&) {
    }
  }
  stylerf::host::Dist::world().finalize();
  return rc;
}
}  // namespace

int main(int argc, char** argv) {
  if (!index_complete()) return 3;
  if (argc < 2 || !std::strcmp(argv[1], "help") || !std::strcmp(argv[1], "--help") || !std::strcmp(argv[1], "-h")) {
    usage(argc < 2 ? std::cerr : std::cout);
    return argc < 2 ? 2 : 0;
  }
  if (!std::strcmp(argv[1], "--version")) return print_version();
  // Under mpirun: MPI before any thread of ours, and only rank 0 prints progress (errors still reach stderr).
  if (stylerf::host::Dist::world().size() > 1 && !stylerf::host::Dist::world().root()) std::cout.rdbuf(nullptr);
  std::vector<char*> args(argv + 1, argv + argc);
  // The old spelling of `eval style` keeps working, with a notice (CHANGELOG.md).
  static char eval_name[] = "eval", style_name[] = "style";
  if (!std::strcmp(argv[1], "eval-style")) {
    std::cerr << "stylerf: eval-style is now `eval style` (the old name will be removed; CHANGELOG.md)\n";
    args.front() = eval_name;
    args.insert(args.begin() + 1, style_name);
  }
  if (const cli::Command* c = find_command(args.front())) {
    if (!runs_over_ranks(c->name, args.size() > 1 ? args[1] : "")) return 2;
    return run_command(*c, int(args.size()), args.data());
  }
  std::cerr << "stylerf: unknown command '" << argv[1] << "'\n";
  usage(std::cerr);
  return 2;
}
