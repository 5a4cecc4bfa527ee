// Every command and subcommand of `stylerf` in one table: its workflow group, a one-line summary and its
// examples. `stylerf help` lists it group by group with each command's first example; each command's
// --help ends with its examples (help.hpp). A command registered without an entry here fails at start-up.
#pragma once
#include <string>
#include <vector>

namespace stylerf::cli {

struct CommandInfo {
  std::string name;                   // "train-density", or "eval style" for a subcommand
  std::string group;                  // one of workflow_groups()
  std::string summary;                // one line
  std::vector<std::string> examples;  // one or two command lines, each starting "stylerf "
};

// The groups in workflow order: get a scene -> train -> stylise -> evaluate -> tools.
const std::vector<std::string>& workflow_groups();
const std::vector<CommandInfo>& command_index();
// The entry of `name` ("eval style" for a subcommand); nullptr when there is none.
const CommandInfo* find_command_info(const std::string& name);
// The entries whose name is "<parent> <sub>", in table order.
std::vector<const CommandInfo*> subcommands_of(const std::string& parent);

}  // namespace stylerf::cli
