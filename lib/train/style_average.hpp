// The uniform average of the weights of several style checkpoints of one run: stochastic weight averaging
// (Izmailov et al. 2018) after the fact, over snapshots that `train-style --snapshot-every N` keeps.
//
// Why: one style image a step keeps the stylizer moving through the end of a run (on fern two runs of one
// recipe differ by 0.25x AdaIN's style loss). Where the iterates wander about a minimum, their average sits
// nearer its middle than any one of them. nn/weight_average.hpp keeps an exponential average during
// training; this one is chosen afterwards, from snapshots, so that the last iterate and averages over
// several stretches can be compared on one run. Measured on fern's 45-minute runs it loses to the last
// iterate (1.66-1.71x against 1.51x AdaIN's style loss: README): those runs are still descending at their
// end, and an average of their last stretch pulls them back.
//
// What is averaged: every trained parameter (SICT, DST, the style decoder; the stage-2 decoder where it is
// the style decoder) and SICT's running statistics (statistics of the frozen field's samples, whatever
// the weights), in double, so a tensor equal in every input stays bit-identical. Everything else must be
// identical in every input (the frozen geometry and field, the style model's kind, the style sets), or it
// is an Error naming the file: averaging checkpoints of different runs is meaningless. Optimiser and
// weight-average state is dropped, so the result is a model to stylise and evaluate with, not to resume.
#pragma once
#include <string>
#include <vector>

#include "lib/io/checkpoint.hpp"

namespace stylerf::train {

// Needs at least two paths, each a style checkpoint. The result's metadata is the last input's (without
// the trainer's state) plus "averaged": {"from": [{"path", "iteration"}...]}.
io::Checkpoint average_style_checkpoints(const std::vector<std::string>& paths);

// "<dir>/<stem>.it<iteration><ext>": where `train-style --snapshot-every` keeps the snapshot of an
// iteration beside the checkpoint `path`.
std::string snapshot_path(const std::string& path, int iteration);

}  // namespace stylerf::train
