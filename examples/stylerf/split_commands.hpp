// The commands that split their work over MPI ranks (host/dist.hpp): the training stages (their steps'
// sub-batches), stylize and render (their views), eval style and eval table (their styles). Any other
// command does the same work on every rank, so it runs on one. `stylerf run --ranks N` starts these under
// mpirun and the others as one process; started under mpirun, the others are refused.
#pragma once
#include <algorithm>
#include <iterator>
#include <string>

namespace stylerf::cli {

// command: the first word ("eval" for eval's subcommands); sub: the second ("style"), or "".
inline bool splits_over_ranks(const std::string& command, const std::string& sub) {
  static const char* const kSplit[] = {"train-density", "train-features", "train-style", "stylize",
                                       "render",        "eval style",     "eval table"};
  const std::string name = command == "eval" && !sub.empty() ? command + " " + sub : command;
  return std::find(std::begin(kSplit), std::end(kSplit), name) != std::end(kSplit);
}

}  // namespace stylerf::cli
