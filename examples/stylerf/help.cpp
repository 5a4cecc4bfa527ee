#include "examples/stylerf/help.hpp"

#include <charconv>
#include <deque>
#include <iostream>

#include "examples/stylerf/command_index.hpp"
#include "host/error.hpp"

namespace stylerf::cli {

namespace po = boost::program_options;

const char* const kDeviceHelp =
    "OpenCL device: index, cpu|gpu|accelerator, or part of a name (default: STYLERF_DEVICE, else the first GPU, "
    "else the first device)";

std::string examples_block(const std::string& command) {
  const CommandInfo* info = find_command_info(command);
  if (!info || info->examples.empty()) throw host::Error("no examples for '" + command + "' in command_index.cpp");
  std::string block = "Examples:\n";
  for (const auto& e : info->examples) block += "  " + e + "\n";
  return block;
}

void print_help(std::ostream& os, const std::string& command, const po::options_description& desc,
                const std::string& notes) {
  os << desc;
  if (!notes.empty()) os << "\n" << notes << (notes.back() == '\n' ? "" : "\n");
  os << "\n" << examples_block(command);
}

namespace {
template <class T>
std::string shortest_text(T v) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);  // shortest round-trip form
  return std::string(buf, r.ptr);
}
}  // namespace

std::string shortest(float v) { return shortest_text(v); }
std::string shortest(double v) { return shortest_text(v); }

po::typed_value<float>* value_shown(float* v) { return po::value(v)->default_value(*v, shortest(*v)); }
po::typed_value<double>* value_shown(double* v) { return po::value(v)->default_value(*v, shortest(*v)); }

void apply_renamed_flags(const std::string& command, int argc, char** argv, std::initializer_list<RenamedFlag> renames) {
  static std::deque<std::string> rewritten;  // argv points into it until the process ends
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--") break;
    for (const RenamedFlag& r : renames) {
      const std::string old_name = r.old_name;
      const bool alone = arg == old_name;
      if (!alone && arg.rfind(old_name + "=", 0) != 0) continue;
      rewritten.push_back(r.new_name + arg.substr(old_name.size()));
      argv[i] = rewritten.back().data();
      std::cerr << "stylerf " << command << ": " << old_name << " is now " << r.new_name
                << " (the old name will be removed; CHANGELOG.md)\n";
      break;
    }
  }
}

}  // namespace stylerf::cli
