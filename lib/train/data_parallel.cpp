#include "lib/train/data_parallel.hpp"

#include <algorithm>
#include <chrono>
#include <iomanip>
#include <sstream>

#include "host/error.hpp"

namespace stylerf::train {

namespace {
// The values of tensors laid end to end, in double.
std::vector<double> flatten(const std::vector<const host::Tensor*>& ts) {
  std::vector<double> flat;
  for (const host::Tensor* t : ts) {
    const std::vector<float> v = t->to_host();
    flat.insert(flat.end(), v.begin(), v.end());
  }
  return flat;
}
}  // namespace

std::string sync_summary(const SyncTotals& s, int ranks) {
  std::ostringstream o;
  o << ranks << (ranks == 1 ? " rank: " : " ranks: ") << std::fixed << std::setprecision(1) << double(s.bytes) / 1e6
    << " MB of gradient a step, " << 1e3 * s.seconds / std::max(1, s.steps)
    << " ms a step (from the device, summed over the ranks, back)";
  return o.str();
}

void GradientSum::add(const std::vector<nn::Param*>& params) {
  std::vector<const host::Tensor*> grads;
  for (nn::Param* p : params) grads.push_back(&p->grad_buffer());
  const std::vector<double> flat = flatten(grads);
  if (sum_.empty()) sum_.assign(flat.size(), 0.0);
  if (sum_.size() != flat.size())
    throw host::Error("GradientSum: " + std::to_string(flat.size()) + " gradient values after " +
                      std::to_string(sum_.size()) + " (the params changed within a step)");
  for (size_t i = 0; i < flat.size(); ++i) sum_[i] += flat[i];
  for (nn::Param* p : params) p->zero_grad();
}

SyncCost GradientSum::average(const std::vector<nn::Param*>& params, double count, host::Dist& dist) {
  const auto t0 = std::chrono::steady_clock::now();
  if (!(count > 0)) throw host::Error("GradientSum: no sub-batch contributed (count " + std::to_string(count) + ")");
  int64_t n = 0;
  for (nn::Param* p : params) n += p->value.numel();
  if (sum_.empty()) sum_.assign(size_t(n), 0.0);  // this rank had no sub-batch in the step
  if (int64_t(sum_.size()) != n)
    throw host::Error("GradientSum: " + std::to_string(sum_.size()) + " gradient values for " + std::to_string(n) +
                      " parameters");
  dist.allreduce_sum(sum_);
  size_t at = 0;
  for (nn::Param* p : params) {
    std::vector<float> g(size_t(p->value.numel()));
    for (float& x : g) x = float(sum_[at++] / count);
    p->grad_buffer().upload(g);
  }
  sum_.clear();
  return {n * int64_t(sizeof(float)), std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count()};
}

BufferMoves::BufferMoves(std::vector<nn::StateBuffer*> buffers) : buffers_(std::move(buffers)) {
  for (nn::StateBuffer* b : buffers_) {
    start_.push_back(b->value.to_host());
    sum_.emplace_back(start_.back().size(), 0.0);
  }
}

void BufferMoves::restart() {
  for (size_t i = 0; i < buffers_.size(); ++i) buffers_[i]->value.upload(start_[i]);
}

void BufferMoves::add() {
  for (size_t i = 0; i < buffers_.size(); ++i) {
    const std::vector<float> v = buffers_[i]->value.to_host();
    for (size_t e = 0; e < v.size(); ++e) sum_[i][e] += v[e];
  }
  count_ += 1;
}

void BufferMoves::finish(host::Dist& dist) {
  std::vector<double> flat{count_};
  for (const auto& s : sum_) flat.insert(flat.end(), s.begin(), s.end());
  dist.allreduce_sum(flat);
  const double n = flat[0];
  size_t at = 1;
  for (size_t i = 0; i < buffers_.size(); ++i) {
    std::vector<float> v = start_[i];
    if (n > 0)
      for (float& x : v) x = float(flat[at++] / n);
    else
      at += v.size();
    buffers_[i]->value.upload(v);
  }
}

}  // namespace stylerf::train
