#include <fruit_shape_completion/parallel_jobs.h>

#include <algorithm>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace fruit_shape_completion {

void runParallelJobs(std::size_t n, int threads, const std::function<void(std::size_t)>& job,
                     const std::atomic<bool>* cancel) {
  std::atomic<std::size_t> next{0};
  std::atomic<bool> failed{false};
  std::exception_ptr error;
  std::mutex error_mutex;
  auto work = [&]() {
    for (;;) {
      if (failed.load() || (cancel != nullptr && cancel->load())) return;
      const std::size_t i = next.fetch_add(1);
      if (i >= n) return;
      try {
        job(i);
      } catch (...) {
        std::lock_guard<std::mutex> lock(error_mutex);
        if (!error) error = std::current_exception();
        failed = true;
      }
    }
  };
  const std::size_t helpers = std::min<std::size_t>(n, static_cast<std::size_t>(std::max(1, threads))) - (n > 0 ? 1 : 0);
  std::vector<std::thread> pool;
  struct Joiner {  // the helpers are joined however this function is left
    std::vector<std::thread>& pool;
    ~Joiner() {
      for (auto& t : pool)
        if (t.joinable()) t.join();
    }
  } joiner{pool};
  try {
    pool.reserve(helpers);
    for (std::size_t t = 0; t < helpers; ++t) pool.emplace_back(work);
  } catch (...) {
    // No (further) thread to be had: the caller's does the rest of the work.
  }
  work();
  for (auto& t : pool) t.join();
  if (error) std::rethrow_exception(error);
}

bool ThreadBudget::tryAcquire() {
  int busy = busy_.load();
  while (busy < threads_)
    if (busy_.compare_exchange_weak(busy, busy + 1)) return true;
  return false;
}

void runPair(ThreadBudget* budget, const std::function<void()>& first, const std::function<void()>& second) {
  if (budget == nullptr || !budget->tryAcquire()) {
    first();
    second();
    return;
  }
  std::exception_ptr first_error, second_error;
  std::thread helper;
  try {
    helper = std::thread([&]() {
      try {
        second();
      } catch (...) {
        second_error = std::current_exception();
      }
      budget->release();
    });
  } catch (...) {  // no thread to be had: both here
    budget->release();
    first();
    second();
    return;
  }
  try {
    first();
  } catch (...) {
    first_error = std::current_exception();
  }
  helper.join();
  if (first_error) std::rethrow_exception(first_error);
  if (second_error) std::rethrow_exception(second_error);
}

}  // namespace fruit_shape_completion
