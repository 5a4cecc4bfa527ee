#include "lib/train/training_loop.hpp"

#include <iomanip>
#include <optional>
#include <ostream>
#include <sstream>

#include "host/dist.hpp"
#include "lib/train/progress.hpp"
#include "lib/train/stage_programs.hpp"

namespace stylerf::train {

namespace {
// Over several ranks every decision that depends on time (the budget's stop, its refits, the schedule's
// progress) must be the same on all of them, or they would leave the loop at different steps and wait for
// each other forever: every rank reads rank 0's clock. All ranks read it at the same points of the loop.
Clock job_clock(const Clock& own) {
  host::Dist& dist = host::Dist::world();
  const Clock local = own ? own : steady_clock_seconds();
  if (dist.size() == 1) return local;
  return [local, &dist] { return dist.broadcast(local()); };
}
}  // namespace

LoopResult run_training_loop(LoopStage& stage, const LoopControl& c) {
  if (!c.programs.empty()) build_stage_programs(c.programs, c.log);
  host::Dist& dist = host::Dist::world();
  // Rank 0 alone writes checkpoints (every rank holds the same model).
  auto save = [&] {
    if (dist.root()) stage.save();
  };
  LoopResult res;
  TrainingBudget budget(c.time_budget_s, job_clock(c.clock));
  double window_s = 0;
  int window_n = 0;
  while (!stage.done()) {
    const int next = stage.iteration() + 1;
    const bool report = c.log && c.log_every > 0 && (next % c.log_every == 0 || next == stage.total());
    stage.before_step(budget);
    budget.start_step();
    stage.step(report);
    window_s += budget.end_step();
    ++window_n;
    ++res.iterations;
    const int it = stage.iteration();
    if (report) {
      const double per_it = window_s / window_n;
      std::ostringstream l;
      l << "it " << it << "/" << stage.total() << stage.window_line(per_it) << std::fixed << std::setprecision(2)
        << "  " << per_it << " s/it  ETA " << hms(budget.limited() ? budget.remaining() : per_it * (stage.total() - it));
      *c.log << l.str() << std::endl;
      window_s = 0;
      window_n = 0;
    }
    stage.after_report();
    if (c.checkpoint_every > 0 && it % c.checkpoint_every == 0 && !stage.done()) save();
    if (dist.broadcast(stage.after_step() ? 1.0 : 0.0) == 0) break;  // rank 0's callback decides
    if (budget.spent()) break;
    if (const std::optional<Refit> r = budget.refit(stage.iteration())) stage.refit(*r);
  }
  res.seconds = budget.elapsed();
  stage.end_of_run();
  save();
  return res;
}

}  // namespace stylerf::train
