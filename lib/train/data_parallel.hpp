// Data parallelism over the job's ranks (host/dist.hpp): a training step is a fixed number of sub-batches
// (a style, a patch, a share of the rays), dealt round robin to the ranks; each rank adds up the gradients
// of its own, then the sum over all ranks divided by the step's count replaces every rank's gradient, so
// every rank applies the same optimiser step and the models never diverge. One process that runs all of a
// step's sub-batches itself takes the same step (up to the order of the sums): the sub-batches are the
// same whatever the number of ranks, because each one's random draws depend on its own index only.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "host/dist.hpp"
#include "lib/nn/module.hpp"

namespace stylerf::train {

// Whether sub-batch j of a step is this rank's (round robin).
inline bool my_share(int j, const host::Dist& dist) { return j % dist.size() == dist.rank(); }

// What one averaging moved and took: the gradient's bytes (float32) and the seconds of the whole exchange
// (from the device, the sum over the ranks, back to the device).
struct SyncCost {
  int64_t bytes = 0;
  double seconds = 0;
};

// A run's averagings so far: how many, their seconds, and the bytes of the last.
struct SyncTotals {
  int steps = 0;
  double seconds = 0;
  int64_t bytes = 0;
  void add(const SyncCost& c) {
    ++steps;
    seconds += c.seconds;
    bytes = c.bytes;
  }
};

// "N ranks: X MB a step, Y ms a step (...)": what the progress summary of a run says of its averagings.
std::string sync_summary(const SyncTotals& s, int ranks);

// A step's gradient over its sub-batches and the ranks: add() after each of this rank's sub-batches takes
// the params' gradients off the device (summed in double) and zeroes them, so that no sub-batch depends on
// how a backward pass adds into a gradient that is not zero; average() sums over the ranks, divides by
// `count` (the sub-batches that contributed, over all ranks) and puts the result in the params' gradients,
// the same on every rank. A rank with no sub-batch in the step adds nothing and still takes part.
class GradientSum {
 public:
  void add(const std::vector<nn::Param*>& params);
  SyncCost average(const std::vector<nn::Param*>& params, double count, host::Dist& dist);

 private:
  std::vector<double> sum_;
};

// Running statistics (state buffers moved by each sub-batch, such as SICT's) as one step of the whole
// batch moves them: each sub-batch moves them from the step's start values, and the step keeps the mean of
// where they went, over all ranks' sub-batches. For a momentum update that is one update towards the mean
// of the sub-batches' statistics; with one sub-batch, exactly that sub-batch's update.
class BufferMoves {
 public:
  explicit BufferMoves(std::vector<nn::StateBuffer*> buffers);  // remembers the step's start values
  void restart();                  // back to the start values, before a sub-batch moves them
  void add();                      // where the sub-batch that just ran moved them
  void finish(host::Dist& dist);   // the mean of the added values over all ranks; the start values if none

 private:
  std::vector<nn::StateBuffer*> buffers_;
  std::vector<std::vector<float>> start_;
  std::vector<std::vector<double>> sum_;
  double count_ = 0;
};

}  // namespace stylerf::train
