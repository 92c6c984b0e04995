// A fixed split of indexed work over a few threads (perception registers a frame's detections on
// them), with the workers' exceptions handed to the caller rather than ending the process.
#pragma once

#include <cstddef>
#include <exception>
#include <functional>
#include <thread>
#include <vector>

namespace moslam {

// Calls fn(i) for every i in [0, n): on the calling thread when workers <= 1 or n <= 1, else on
// min(workers, n) threads, index i on worker i % that many (the same split on every call:
// per-index outputs need no lock). A worker that throws skips its own remaining indices; the
// others run all of theirs. Once every worker has joined, the exception of the lowest-numbered
// worker that threw is rethrown on the caller. On the calling thread the first exception
// propagates at once (the indices after it do not run).
inline void ForEachOnWorkers(std::size_t n, std::size_t workers,
                             const std::function<void(std::size_t)>& fn) {
  if (workers <= 1 || n <= 1) {
    for (std::size_t i = 0; i < n; ++i) fn(i);
    return;
  }
  if (workers > n) workers = n;
  std::vector<std::exception_ptr> errors(workers);
  std::vector<std::thread> pool;
  pool.reserve(workers);
  for (std::size_t w = 0; w < workers; ++w) {
    pool.emplace_back([&, w] {
      try {
        for (std::size_t i = w; i < n; i += workers) fn(i);
      } catch (...) {
        errors[w] = std::current_exception();
      }
    });
  }
  for (std::thread& th : pool) th.join();
  for (const std::exception_ptr& e : errors) {
    if (e) std::rethrow_exception(e);
  }
}

}  // namespace moslam
