#include "lib/viewer/fair_scheduler.hpp"

#include <algorithm>

namespace stylerf::viewer {

FairScheduler::FairScheduler() : worker_([this] { worker_loop(); }) {}

FairScheduler::~FairScheduler() { stop(); }

void FairScheduler::finish(Task& t, Outcome o) {
  t.done = true;
  t.outcome = o;
  if (o == Outcome::Superseded) ++superseded_;
  task_done_.notify_all();
}

FairScheduler::Outcome FairScheduler::run(const std::string& client, Work work) {
  auto task = std::make_shared<Task>();
  task->work = std::move(work);
  std::unique_lock<std::mutex> lock(mu_);
  if (stopping_) return Outcome::Stopped;
  if (auto it = pending_.find(client); it != pending_.end()) {
    finish(*it->second, Outcome::Superseded);  // never started
    it->second = task;
  } else {
    pending_[client] = task;
    turn_.push_back(client);
  }
  if (auto it = running_.find(client); it != running_.end()) it->second->cancel = true;
  work_ready_.notify_one();
  task_done_.wait(lock, [&] { return task->done; });
  if (task->error) std::rethrow_exception(task->error);
  return task->outcome;
}

void FairScheduler::worker_loop() {
  std::unique_lock<std::mutex> lock(mu_);
  for (;;) {
    work_ready_.wait(lock, [&] { return stopping_ || !turn_.empty(); });
    if (stopping_) return;
    const std::string client = turn_.front();
    turn_.pop_front();
    std::shared_ptr<Task> task = pending_[client];
    pending_.erase(client);
    running_[client] = task;
    lock.unlock();
    std::exception_ptr error;
    try {
      task->work(task->cancel);
    } catch (...) {
      error = std::current_exception();
    }
    lock.lock();
    running_.erase(client);
    if (task->cancel) {
      finish(*task, stopping_ ? Outcome::Stopped : Outcome::Superseded);
    } else {
      task->error = error;
      if (!error) ++completed_;
      finish(*task, Outcome::Done);
    }
  }
}

void FairScheduler::stop() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (!stopping_) {
      stopping_ = true;
      for (auto& [client, t] : running_) t->cancel = true;
      for (auto& [client, t] : pending_) finish(*t, Outcome::Stopped);
      pending_.clear();
      turn_.clear();
      work_ready_.notify_all();
    }
  }
  if (worker_.joinable() && std::this_thread::get_id() != worker_.get_id()) worker_.join();
}

}  // namespace stylerf::viewer
