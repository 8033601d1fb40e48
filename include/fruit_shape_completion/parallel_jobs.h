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

}  // namespace fruit_shape_completion
