// One worker thread that runs work for many clients, one piece at a time, fairly, keeping only the newest
// request of each client: what an interactive viewer needs from a single device shared by several tabs.
//   - Each client has one slot. A newer submit replaces the client's pending work (the replaced submit
//     returns Superseded at once) and raises the cancel flag of its running work, which the work checks
//     between its steps (the submit that started it returns Superseded when it ends).
//   - Clients with pending work are served in turn (round robin), so a busy tab cannot starve another.
//   - The submitter blocks until its work ran (or was superseded); the work's exception reaches it.
// Nothing here knows what the work is.
#pragma once
#include <atomic>
#include <condition_variable>
#include <deque>
#include <exception>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

namespace stylerf::viewer {

class FairScheduler {
 public:
  using Work = std::function<void(const std::atomic<bool>& cancel)>;
  enum class Outcome { Done, Superseded, Stopped };

  FairScheduler();
  ~FairScheduler();  // stop()
  FairScheduler(const FairScheduler&) = delete;
  FairScheduler& operator=(const FairScheduler&) = delete;

  // Runs work on the worker thread for `client` and waits for it. Rethrows what the work threw, unless its
  // cancel flag was raised by then (Superseded or Stopped).
  Outcome run(const std::string& client, Work work);
  // Cancels the running work, answers every pending submit with Stopped, refuses later ones (Stopped), and
  // joins the worker. Idempotent.
  void stop();

  // Counters for tests and the viewer's status: pieces of work run to the end, and superseded.
  int64_t completed() const { return completed_.load(); }
  int64_t superseded() const { return superseded_.load(); }

 private:
  struct Task {
    Work work;
    std::atomic<bool> cancel{false};
    bool done = false;
    Outcome outcome = Outcome::Done;
    std::exception_ptr error;
  };
  void worker_loop();
  void finish(Task& t, Outcome o);  // under mu_

  std::mutex mu_;
  std::condition_variable work_ready_, task_done_;
  std::map<std::string, std::shared_ptr<Task>> pending_, running_;
  std::deque<std::string> turn_;  // clients with pending work, in the order they are served
  bool stopping_ = false;
  std::atomic<int64_t> completed_{0}, superseded_{0};
  std::thread worker_;
};

}  // namespace stylerf::viewer
