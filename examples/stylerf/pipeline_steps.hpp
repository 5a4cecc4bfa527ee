// The steps of `stylerf run`: each is one stylerf subcommand run as a child process (its own memory, its
// own OpenCL runtime, its progress lines shown as they come and kept in OUT/logs/<step>.log).
//
// Resuming: OUT/steps.json records, per step, a key (the step's arguments, the keys of the steps it
// reads, and a fingerprint of its input folders) and the seconds it took. A step whose key matches and
// whose output exists is skipped, so a killed run resumes at the step it was in, and a changed option
// reruns that step and every step after it that reads it. The record is written atomically after each
// step, never before it ends.
#pragma once
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace stylerf::cli {

// Names, sizes and modification times of the files under `dir` (sorted): what makes a scene or a style
// folder "the same inputs" for a step.
std::string folder_fingerprint(const std::string& dir);

class PipelineSteps {
 public:
  // out: the run's folder; self: the stylerf executable to run the steps with.
  PipelineSteps(std::string out, std::string self);

  struct Result {
    double seconds = 0;  // this run's, or the recorded one of a skipped step
    bool skipped = false;
    std::string key;
  };

  // Runs `stylerf <args...>` unless a step `name` with the same key already made `output`. `extra_key`
  // is added to the key (upstream steps' keys, input fingerprints). Throws, naming the step and its log,
  // when the child fails.
  Result run(const std::string& name, const std::vector<std::string>& args, const std::string& output,
             const std::string& extra_key = "");

  // Steps whose command splits over MPI ranks (split_commands.hpp) run as `<launcher...> -np <ranks> self
  // <args...>` (launcher: "mpirun" and its options); the rank count is part of their key. ranks 1: as one
  // process, keys as before.
  void split_over_ranks(int ranks, std::vector<std::string> launcher);

  // Per step: its key, seconds and peak resident memory (MB).
  const nlohmann::json& record() const { return record_; }

 private:
  std::string out_, self_;
  int ranks_ = 1;
  std::vector<std::string> launcher_;
  nlohmann::json record_;
};

}  // namespace stylerf::cli
