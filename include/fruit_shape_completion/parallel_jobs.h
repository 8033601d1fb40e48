#pragma once
// Independent jobs on a few threads: the fits of the clusters one view changed. A view that
// finds many fruits at once is the slowest of an episode, and its fits need not wait for one
// another.
#include <atomic>
#include <cstddef>
#include <functional>

namespace fruit_shape_completion {

// Runs job(0) .. job(n - 1), each once, on up to `threads` threads (the caller's among them;
// 1: all in the caller's thread, in order). Jobs not yet started when *cancel becomes true
// are skipped. The first exception a job throws is rethrown here once all threads are done;
// the jobs not yet started then are skipped too.
void runParallelJobs(std::size_t n, int threads, const std::function<void(std::size_t)>& job,
                     const std::atomic<bool>* cancel = nullptr);

// The threads a set of jobs may keep busy. A view's slowest cluster is often one long chain of
// split tries while the other threads have run out of clusters: a job whose work divides in two
// independent halves lends one half to a new thread while fewer than `threads` are busy.
class ThreadBudget {
 public:
  explicit ThreadBudget(int threads) : threads_(threads) {}
  // A thread busy for the object's lifetime, whether or not the budget had room.
  class Busy {
   public:
    explicit Busy(ThreadBudget& budget) : budget_(budget) { budget_.busy_.fetch_add(1); }
    ~Busy() { budget_.busy_.fetch_sub(1); }
    Busy(const Busy&) = delete;
    Busy& operator=(const Busy&) = delete;

   private:
    ThreadBudget& budget_;
  };
  // One more busy thread if the budget has room.
  bool tryAcquire();
  void release() { busy_.fetch_sub(1); }

 private:
  int threads_;
  std::atomic<int> busy_{0};
};

// first() in the caller's thread and second() beside it on a new thread if `budget` (may be
// null) has room, else after first(). Returns when both are done; rethrows the first exception
// either threw.
void runPair(ThreadBudget* budget, const std::function<void()>& first, const std::function<void()>& second);

}  // namespace fruit_shape_completion
