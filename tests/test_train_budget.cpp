// The training loops' time budget (lib/train/budget.hpp) on synthetic step times: training time, when the
// budget is spent, and the refit's arithmetic, exactly. Step times are binary fractions so that every sum
// is exact.
#include <doctest/doctest.h>

#include <vector>

#include "lib/train/budget.hpp"

using stylerf::train::Refit;
using stylerf::train::TrainingBudget;

namespace {

// A budget whose clock makes the k-th step (1-based) last step_s[k - 1] seconds; every step is bracketed
// by start_step/end_step, as the loops do.
struct Scripted {
  double now = 0;
  TrainingBudget budget;
  explicit Scripted(double seconds) : budget(seconds, [this] { return now; }) {}
  double step(double s) {
    budget.start_step();
    now += s;
    return budget.end_step();
  }
};

}  // namespace

TEST_CASE("without a budget the steps are timed, nothing is ever spent and no refit comes") {
  Scripted b(0);
  for (int k = 1; k <= 100; ++k) CHECK(b.step(0.5) == 0.5);
  CHECK(b.budget.elapsed() == 50.0);
  CHECK_FALSE(b.budget.spent());
  CHECK_FALSE(b.budget.refit(100).has_value());
  CHECK(b.budget.fraction() == 0.0);
}

TEST_CASE("time outside the steps (checkpoints, evaluations) is not training time") {
  Scripted b(10);
  b.step(1.0);
  b.now += 100;  // a checkpoint write between steps
  b.step(0.25);
  CHECK(b.budget.elapsed() == 1.25);
  CHECK(b.budget.fraction() == 0.125);
  CHECK(b.budget.remaining() == 8.75);
}

TEST_CASE("the first refit comes after 10 measured steps, from their rate: the slow first step is left out") {
  Scripted b(4.0);
  b.step(1.0);  // the first step: kernels' code generation, first-touch of buffers
  for (int k = 2; k <= 10; ++k) {
    b.step(0.125);
    CHECK_FALSE(b.budget.refit(k).has_value());  // 9 measured steps: not yet
  }
  b.step(0.125);
  const auto r = b.budget.refit(11);
  REQUIRE(r.has_value());
  // 2.25 s spent, 1.75 s left at 0.125 s a step: 14 more steps, so the run ends at iteration 25. (With
  // the first step in the rate, 2.25 / 11 s a step, it would have fitted 11 + 8 = 19.)
  CHECK(r->seconds_per_step == 0.125);
  CHECK(r->total_iters == 25);
  CHECK(b.budget.refit(11) == std::nullopt);  // consumed
}

TEST_CASE("later refits wait for 10 more steps and 5% of the budget, and use the rate since the last") {
  Scripted b(100.0);
  for (int k = 1; k <= 11; ++k) b.step(0.25);
  REQUIRE(b.budget.refit(11).has_value());  // at 2.75 s; the next no earlier than 2.75 + 5 s
  for (int k = 12; k <= 30; ++k) {
    b.step(0.25);
    CHECK_FALSE(b.budget.refit(k).has_value());  // 10+ steps from step 21, but under 5 s until step 31
  }
  b.step(0.25);
  const auto r = b.budget.refit(31);
  REQUIRE(r.has_value());
  CHECK(r->total_iters == 31 + 369);  // 7.75 s spent, 92.25 s left at 0.25 s a step
  // Steps twice as slow from here: the next refit sees only them (not the run's average).
  for (int k = 32; k <= 50; ++k) b.step(0.5);
  const auto slow = b.budget.refit(50);
  REQUIRE(slow.has_value());
  CHECK(slow->seconds_per_step == 0.5);
  CHECK(slow->total_iters == 50 + 165);  // 17.25 s spent, 82.75 s left: 165.5 steps, rounded down
}

TEST_CASE("the budget is spent at the step that reaches it; a resumed run's refit counts from its iteration") {
  Scripted b(4.0);
  b.step(1.0);
  for (int k = 2; k <= 11; ++k) b.step(0.0625);
  // A run resumed at iteration 1000: 1.625 s spent, 2.375 s left at 1/16 s a step: 38 more.
  const auto r = b.budget.refit(1000 + 11);
  REQUIRE(r.has_value());
  CHECK(r->total_iters == 1011 + 38);
  for (int k = 12; k <= 48; ++k) {
    b.step(0.0625);
    CHECK_FALSE(b.budget.spent());
  }
  b.step(0.0625);  // the 38th after the refit: 4.0 s exactly
  CHECK(b.budget.spent());
}

TEST_CASE("a clock too coarse to see a step cannot overflow the fitted length") {
  Scripted b(60.0);
  for (int k = 1; k <= 11; ++k) b.step(0.0);
  const auto r = b.budget.refit(11);
  REQUIRE(r.has_value());
  CHECK(r->total_iters == 11 + 1000000000);
}
