#pragma once
// One background thread that runs a job (an estimator's fit) whenever asked. Requests that
// arrive while the job runs coalesce into one more run on the newest state, so a job slower
// than the requests never builds a backlog, and the caller never waits for it.
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <functional>
#include <mutex>
#include <thread>

namespace fruit_shape_completion {
namespace host {

class UpdateWorker {
 public:
  struct Status {
    std::size_t runs = 0;       // finished runs
    std::size_t coalesced = 0;  // requests folded into a pending run
    std::size_t failed = 0;     // runs that threw (the job should catch; this is the last net)
    double last_seconds = 0.0;  // duration of the last finished run
    double age_seconds = -1.0;  // since the last run finished; < 0: none yet
    bool running = false, pending = false;
  };

  explicit UpdateWorker(std::function<void()> job);
  ~UpdateWorker();  // stop()
  UpdateWorker(const UpdateWorker&) = delete;
  UpdateWorker& operator=(const UpdateWorker&) = delete;

  void request();
  // No further runs; waits for a running one to return (make it return early first).
  void stop();
  // Until nothing is pending or running, or `timeout` seconds: for tests and benchmarks.
  bool waitIdle(double timeout) const;
  Status status() const;

 private:
  void loop();
  std::function<void()> job_;
  mutable std::mutex mutex_;
  mutable std::condition_variable changed_;
  bool pending_ = false, running_ = false, stop_ = false;
  std::size_t runs_ = 0, coalesced_ = 0, failed_ = 0;
  double last_seconds_ = 0.0;
  std::chrono::steady_clock::time_point last_finished_;
  std::thread thread_;  // last: starts after the members it uses
};

}  // namespace host
}  // namespace fruit_shape_completion
