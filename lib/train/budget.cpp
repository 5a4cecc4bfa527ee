#include "lib/train/budget.hpp"

#include <algorithm>
#include <chrono>

namespace stylerf::train {

Clock steady_clock_seconds() {
  return [] { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); };
}

TrainingBudget::TrainingBudget(double seconds, Clock clock)
    : seconds_(seconds), clock_(clock ? std::move(clock) : steady_clock_seconds()) {}

void TrainingBudget::start_step() { started_ = clock_(); }

double TrainingBudget::end_step() {
  const double s = clock_() - started_;
  elapsed_ += s;
  if (++steps_ > 1) {  // the first step is not measured (see the header)
    window_s_ += s;
    ++window_steps_;
  }
  return s;
}

std::optional<Refit> TrainingBudget::refit(int done) {
  if (!limited() || window_steps_ < kFirstRefitSteps || elapsed_ < next_refit_at_) return std::nullopt;
  const double per_step = window_s_ / window_steps_;
  // Capped so that a clock too coarse to see a step (0 s) cannot overflow the count.
  const double fit = std::min(std::max(0.0, remaining()) / std::max(per_step, 1e-12), 1e9);
  window_s_ = 0;
  window_steps_ = 0;
  next_refit_at_ = elapsed_ + kRefitEvery * seconds_;
  return Refit{done + std::max(1, int(fit)), per_step};
}

}  // namespace stylerf::train
