// The one training loop of the three stages: the stage's kernels are built before it (stage_programs),
// then each step is timed against the budget (lib/train/budget.hpp), a progress line closes every
// log_every steps (the stage's losses over the window, s/it, ETA), checkpoints are written every
// checkpoint_every steps (atomically) and at the end, a callback may stop the run after any step, and the
// run's length is refitted to the budget as the step rate becomes known.
//
// A stage plugs in through LoopStage: its step, its window of statistics and what a refit changes. The
// clock is LoopControl's, so tests drive the refits with synthetic step times.
#pragma once
#include <functional>
#include <iosfwd>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "host/runtime.hpp"

#include "lib/train/budget.hpp"

namespace stylerf::train {

// The options every stage's run takes; each stage's options add their own fields and their own cadences.
template <class StepStats>
struct LoopOptions {
  std::ostream* log = nullptr;
  int log_every = 100;
  std::string checkpoint;       // empty: none
  int checkpoint_every = 1000;  // and always at the end
  nlohmann::json scene_meta;
  double time_budget_s = 0;  // > 0: stop after this much training time (lib/train/budget.hpp)
  Clock clock;               // read before and after each step; empty: the steady clock
  // Called after every step (and its periodic checkpoint); return false to stop early. An exception
  // thrown here leaves the loop without the final checkpoint (the periodic ones are atomic).
  std::function<bool(const StepStats&)> after_step;
};

// One stage as the loop sees it.
class LoopStage {
 public:
  virtual ~LoopStage() = default;
  virtual bool done() const = 0;
  virtual int iteration() const = 0;  // steps completed
  virtual int total() const = 0;      // the run's length as it stands now
  // Before a step, outside its timing (the style stage follows the budget's fraction here).
  virtual void before_step(const TrainingBudget&) {}
  // One step, its statistics added to the stage's window. `report`: a progress line follows (a stage may
  // measure more for it).
  virtual void step(bool report) = 0;
  // The stage's part of the progress line, over the window since the last one (which it then clears):
  // text to follow "it N/TOTAL", starting with its own separator. `per_it`: the window's seconds a step.
  virtual std::string window_line(double per_it) = 0;
  // After the step and its progress line, untimed (held-out evaluations).
  virtual void after_report() {}
  // The caller's callback on the last step's statistics: false stops the run.
  virtual bool after_step() = 0;
  // The budget's refit of the run's length.
  virtual void refit(const Refit& r) = 0;
  virtual void save() = 0;  // a checkpoint, when the run has a path
  // After the last step, before the final checkpoint (a stage keeps its last window's figures).
  virtual void end_of_run() {}
};

// A LoopStage over a trainer that has done() and iteration() (the three stages' trainers), its run's
// options, and the last step's statistics (last_, which the stage's step() sets) for the options' callback.
template <class Trainer, class Options, class StepStats>
class TrainerLoopStage : public LoopStage {
 public:
  TrainerLoopStage(Trainer& t, const Options& o) : t_(t), o_(o) {}
  bool done() const override { return t_.done(); }
  int iteration() const override { return t_.iteration(); }
  bool after_step() override { return !o_.after_step || o_.after_step(last_); }

 protected:
  Trainer& t_;
  const Options& o_;
  StepStats last_;
};

struct LoopControl {
  std::vector<host::ProgramBuild> programs;  // built before the clock starts (lib/train/stage_programs.hpp)
  std::ostream* log = nullptr;
  int log_every = 100;
  int checkpoint_every = 1000;
  double time_budget_s = 0;
  Clock clock;
};
template <class StepStats>
LoopControl loop_control(const LoopOptions<StepStats>& o, std::vector<host::ProgramBuild> programs) {
  return {std::move(programs), o.log, o.log_every, o.checkpoint_every, o.time_budget_s, o.clock};
}

struct LoopResult {
  int iterations = 0;  // steps taken in this run
  double seconds = 0;  // training time (checkpoints, evaluations and kernel builds excluded)
};

// Builds the programs, then runs `stage` until it is done, the budget is spent or its after_step says stop;
// then saves.
LoopResult run_training_loop(LoopStage& stage, const LoopControl& c);

}  // namespace stylerf::train
