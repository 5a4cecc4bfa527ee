// The parts of the command-line grammar every command shares: its --help page (options, notes, then the
// examples from command_index.hpp), defaults printed as a user would type them, and old flag spellings that
// keep working with a one-line notice (CHANGELOG.md lists the renames).
#pragma once
#include <boost/program_options.hpp>
#include <initializer_list>
#include <ostream>
#include <string>

namespace stylerf::cli {

// `command`'s --help: `desc`, then `notes` (if any, after a blank line), then its "Examples:" block.
void print_help(std::ostream& os, const std::string& command, const boost::program_options::options_description& desc,
                const std::string& notes = "");
// "Examples:\n  stylerf ...\n" for `command` ("eval style" for a subcommand); an error when it has none.
std::string examples_block(const std::string& command);

// --device's help, the same on every command: what SPEC may be, and the device chosen without it.
extern const char* const kDeviceHelp;

// The shortest decimal text that reads back as the same value: 0.03f prints "0.03", not "0.0299999993".
std::string shortest(float v);
std::string shortest(double v);
// An option value whose default is printed by shortest() (boost prints floats with 9 digits).
boost::program_options::typed_value<float>* value_shown(float* v);
boost::program_options::typed_value<double>* value_shown(double* v);

// An old flag spelling and the flag that replaced it.
struct RenamedFlag {
  const char* old_name;  // "--profile"
  const char* new_name;  // "--timing"
};
// Rewrites argv[1..argc) in place: each old spelling (alone or as "--old=value") becomes the new one, and one
// line on stderr says so, naming `command`.
void apply_renamed_flags(const std::string& command, int argc, char** argv, std::initializer_list<RenamedFlag> renames);

}  // namespace stylerf::cli
