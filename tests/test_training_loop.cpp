// The one training loop (lib/train/training_loop.hpp) driving a scripted stage with a synthetic clock: the
// progress lines' cadence and content, checkpoints, the caller's stop, the budget's stop and refits, and
// that time outside the steps is not training time. No OpenCL: the stage is plain C++.
#include <doctest/doctest.h>

#include <sstream>
#include <string>
#include <vector>

#include "lib/train/training_loop.hpp"

using namespace stylerf::train;

namespace {

// A stage of `total` steps, each taking step_s seconds of the scripted clock, with a checkpoint and an
// evaluation that take time too (which must not count).
struct ScriptedStage : LoopStage {
  double now = 0, step_s = 0.5;
  int it = 0, total_ = 10, stop_after = -1;
  std::vector<int> saves, reports, refits;
  int windows = 0, ended = 0;
  bool done() const override { return it >= total_; }
  int iteration() const override { return it; }
  int total() const override { return total_; }
  void step(bool report) override {
    ++it;
    now += step_s;
    if (report) reports.push_back(it);
  }
  std::string window_line(double per_it) override {
    ++windows;
    std::ostringstream l;
    l << "  window " << windows << " at " << per_it;
    return l.str();
  }
  void after_report() override { now += 7.0; }  // an evaluation: untimed
  bool after_step() override { return it != stop_after; }
  void refit(const Refit& r) override {
    refits.push_back(r.total_iters);
    total_ = r.total_iters;
  }
  void save() override {
    saves.push_back(it);
    now += 3.0;  // a checkpoint write: untimed
  }
  void end_of_run() override { ++ended; }
};

LoopControl control(ScriptedStage& s, std::ostream* log, int log_every, int checkpoint_every, double budget) {
  LoopControl c;
  c.log = log;
  c.log_every = log_every;
  c.checkpoint_every = checkpoint_every;
  c.time_budget_s = budget;
  c.clock = [&s] { return s.now; };
  return c;
}

}  // namespace

TEST_CASE("the loop runs a stage to its end: progress lines, checkpoints, the final save") {
  ScriptedStage s;
  std::ostringstream log;
  const LoopResult r = run_training_loop(s, control(s, &log, 4, 3, 0));
  CHECK(r.iterations == 10);
  CHECK(r.seconds == 5.0);  // 10 steps of 0.5 s; the evaluations and checkpoints are not counted
  CHECK(s.reports == std::vector<int>{4, 8, 10});  // every 4 steps, and the last
  CHECK(s.saves == std::vector<int>{3, 6, 9, 10});  // every 3 steps, none at the end twice, then the final one
  CHECK(s.ended == 1);
  const std::string text = log.str();
  CHECK(text.find("it 4/10  window 1 at 0.5") != std::string::npos);
  CHECK(text.find("0.50 s/it  ETA 3s") != std::string::npos);  // 6 steps of 0.5 s left at step 4
  CHECK(text.find("it 10/10  window 3 at 0.5") != std::string::npos);
  CHECK(s.refits.empty());  // no budget, no refit
}

TEST_CASE("the caller's after_step stops the run, which still ends with a checkpoint") {
  ScriptedStage s;
  s.stop_after = 5;
  const LoopResult r = run_training_loop(s, control(s, nullptr, 0, 0, 0));
  CHECK(r.iterations == 5);
  CHECK(s.saves == std::vector<int>{5});
  CHECK(s.reports.empty());  // no log: no progress lines, and the stage is never asked for them
}

TEST_CASE("a time budget stops the run when spent and refits its length from the measured rate") {
  ScriptedStage s;
  s.total_ = 1000;
  s.step_s = 0.25;
  // 10 s of training at 0.25 s a step: 40 steps fit. The first refit comes after the first
  // TrainingBudget::kFirstRefitSteps measured steps (the first step is never measured).
  const LoopResult r = run_training_loop(s, control(s, nullptr, 0, 0, 10.0));
  CHECK(r.iterations == 40);
  CHECK(r.seconds == 10.0);
  REQUIRE_FALSE(s.refits.empty());
  CHECK(s.refits.front() == 40);
  CHECK(s.total_ == 40);
  CHECK(s.saves == std::vector<int>{40});
}
