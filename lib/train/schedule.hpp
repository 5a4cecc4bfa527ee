// TensoRF's density-stage schedules, as plain functions of the iteration count (so --resume reproduces them).
//
// Iterations are counted as completed steps: step k (1-based) runs, then events at k fire (an upsample at
// 2000 happens after the 2000th step, as TensoRF's `if iteration in upsamp_list` after its optimizer step).
//
// - Grid size: voxel counts grow log-linearly from voxels_init to voxels_final over the upsample list
//   (TensoRF: round(exp(linspace(log init, log final, n + 1)))[1:]).
// - Learning rate: multiplied by ratio^(1/iters) every step (0.1x over the run). TensoRF rebuilds its Adam
//   optimizer at every upsample with lr_upsample_reset = 1, so the rate jumps back to its initial value and
//   decays again from there; lr_reset_on_upsample reproduces that (off: one smooth decay to 0.1x).
// - Regulariser weights (TV) decay with the same factor every step but are never reset (as TensoRF).
#pragma once
#include <cstdint>
#include <string>
#include <vector>

namespace stylerf::train {

struct Schedule {
  int iters = 30000;
  std::vector<int> upsample_at{2000, 3000, 4000, 5500};
  int64_t voxels_init = 128LL * 128 * 128;
  int64_t voxels_final = 300LL * 300 * 300;
  std::vector<int> mask_at{2000, 4000};
  float lr_decay_ratio = 0.1f;
  bool lr_reset_on_upsample = true;

  void validate() const;  // throws host::Error naming the bad field
  // Voxel counts after each upsample (same length as upsample_at).
  std::vector<int64_t> voxel_list() const;
  // Voxels in effect after `done` completed steps (voxels_init before the first upsample).
  int64_t voxels_after(int done) const;
  // Learning-rate multiplier for step k (1-based).
  float lr_scale(int step) const;
  // Regulariser-weight multiplier for step k (1-based).
  float reg_scale(int step) const;
  bool upsample_at_step(int done) const;
  bool mask_at_step(int done) const;
  bool first_mask_step(int done) const { return !mask_at.empty() && done == mask_at.front(); }
  // The same schedule for a run of `iters` steps: events stay at their iterations when they all fall in
  // the first 80% of the run; otherwise every event is scaled by the same factor so the last lands at 80%,
  // but never so far that the first comes before `min_first` (a mask or an upsample of a model a few dozen
  // steps old would be built from noise). Every event is kept (one past the end never fires), so the voxel
  // list is unchanged. Measured on lego 1/4 in 30 min: scaling TensoRF's events by the run's length alone
  // (mask at 112, 300^3 by 1349 of ~4500) reached 30.6 dB at 1050 s, against 32.4 dB at 30 min for its
  // events unmoved.
  Schedule fitted(int iters, int min_first = 100) const;
  // "upsample at 2000 3000 ... to 2.1M 4.6M ... voxels; alpha mask at 2000 4000; lr 0.1x over 30000".
  std::string describe() const;
};

// Parses "2000,3000,4000" (empty string: empty list). Throws host::Error naming `flag`.
std::vector<int> parse_int_list(const std::string& s, const std::string& flag);

}  // namespace stylerf::train
