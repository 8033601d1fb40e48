#include <fruit_shape_completion/host/update_worker.h>

namespace fruit_shape_completion {
namespace host {

UpdateWorker::UpdateWorker(std::function<void()> job) : job_(std::move(job)), thread_([this] { loop(); }) {}

UpdateWorker::~UpdateWorker() { stop(); }

void UpdateWorker::request() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (stop_) return;
  if (pending_) ++coalesced_;
  pending_ = true;
  changed_.notify_all();
}

void UpdateWorker::stop() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
    pending_ = false;
    changed_.notify_all();
  }
  if (thread_.joinable() && thread_.get_id() != std::this_thread::get_id()) thread_.join();
}

bool UpdateWorker::waitIdle(double timeout) const {
  std::unique_lock<std::mutex> lock(mutex_);
  return changed_.wait_for(lock, std::chrono::duration<double>(timeout), [this] { return !pending_ && !running_; });
}

UpdateWorker::Status UpdateWorker::status() const {
  std::lock_guard<std::mutex> lock(mutex_);
  Status s;
  s.runs = runs_;
  s.coalesced = coalesced_;
  s.failed = failed_;
  s.last_seconds = last_seconds_;
  if (runs_ > 0) s.age_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - last_finished_).count();
  s.running = running_;
  s.pending = pending_;
  return s;
}

void UpdateWorker::loop() {
  std::unique_lock<std::mutex> lock(mutex_);
  for (;;) {
    changed_.wait(lock, [this] { return pending_ || stop_; });
    if (stop_) return;
    pending_ = false;
    running_ = true;
    lock.unlock();
    const auto start = std::chrono::steady_clock::now();
    bool ok = true;
    try {
      job_();
    } catch (...) {  // never std::terminate in a planner's process
      ok = false;
    }
    const auto end = std::chrono::steady_clock::now();
    lock.lock();
    running_ = false;
    ++runs_;
    failed_ += ok ? 0 : 1;
    last_seconds_ = std::chrono::duration<double>(end - start).count();
    last_finished_ = end;
    changed_.notify_all();
  }
}

}  // namespace host
}  // namespace fruit_shape_completion
