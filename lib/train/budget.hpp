// The time budget of a training loop (--minutes) and the refits of the run's length to it: one policy for
// the three stages' loops.
//
// Time is training time: each step's own, read from a Clock just before and just after it. Checkpoint
// writes, held-out evaluations and the kernel builds before the first step are not counted. The clock is
// the caller's to replace, so tests drive the refit with synthetic step times.
//
// A refit sizes the rest of the run from the step rate measured since the previous refit: first after
// kFirstRefitSteps measured steps, then after as many again and at least kRefitEvery of the budget. The
// first step of a run is never measured: it also pays for the run's one-off work (PoCL generating each
// kernel's code at its first launch, first-touch page faults of new buffers), and a rate taken from it
// would fit too few steps and pull the schedule's events in too far.
#pragma once
#include <functional>
#include <optional>

namespace stylerf::train {

// Seconds from any fixed origin.
using Clock = std::function<double()>;
Clock steady_clock_seconds();

struct Refit {
  int total_iters = 0;          // the iteration the run should end at (done + the steps that fit)
  double seconds_per_step = 0;  // the rate it was fitted from
};

class TrainingBudget {
 public:
  static constexpr int kFirstRefitSteps = 10;
  static constexpr double kRefitEvery = 0.05;

  // seconds <= 0: no budget (the steps are still timed). An empty clock is the steady clock.
  explicit TrainingBudget(double seconds, Clock clock = {});

  // Bracket one step: the time between them is training time. end_step returns the step's seconds.
  void start_step();
  double end_step();

  bool limited() const { return seconds_ > 0; }
  double elapsed() const { return elapsed_; }
  bool spent() const { return limited() && elapsed_ >= seconds_; }
  double remaining() const { return seconds_ - elapsed_; }
  double fraction() const { return limited() ? elapsed_ / seconds_ : 0.0; }
  // After a step, `done` the trainer's completed iterations: the run's length that fits the rest of the
  // budget when a refit is due (see above), else nothing.
  std::optional<Refit> refit(int done);

 private:
  double seconds_;
  Clock clock_;
  double started_ = 0, elapsed_ = 0;
  int steps_ = 0;
  double window_s_ = 0;  // measured since the last refit
  int window_steps_ = 0;
  double next_refit_at_ = 0;
};

}  // namespace stylerf::train
