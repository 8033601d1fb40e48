#pragma once
// Splitting work over a few threads without letting an exception escape a thread (which would
// end the process): for the TSDF integrator's passes and the renderer's tiles.
#include <cstddef>
#include <exception>
#include <thread>
#include <vector>

namespace fruit_shape_completion {

// Runs part(t) for t in [0, parts): part 0 on this thread, the others on their own (or here, if
// no thread can be had). Nothing may escape a part before every thread is joined: each part
// keeps its exception, the first one is rethrown afterwards (as one thread doing all parts
// would throw it).
template <typename Part>
void runParts(std::size_t parts, Part&& part) {
  std::vector<std::exception_ptr> errors(parts);
  auto guarded = [&](std::size_t t) {
    try {
      part(t);
    } catch (...) {
      errors[t] = std::current_exception();
    }
  };
  std::vector<std::thread> pool;
  for (std::size_t t = 1; t < parts; ++t) {
    try {
      pool.emplace_back(guarded, t);
    } catch (...) {
      guarded(t);
    }
  }
  if (parts > 0) guarded(0);
  for (auto& th : pool) th.join();
  for (const auto& e : errors)
    if (e) std::rethrow_exception(e);
}

}  // namespace fruit_shape_completion
