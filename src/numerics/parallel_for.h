// A deterministic parallel loop (internal): task(i, worker) for every i in [0, count) on up to
// `threads` threads, worker in [0, threads) (the caller's thread is worker 0). Each index runs
// exactly once, so results a task writes to slot i do not depend on the thread count. The first
// exception a task throws stops the hand-out of further indices and is rethrown once every thread
// has finished.
#pragma once

#include <algorithm>
#include <atomic>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace millkit::numerics {

template <typename Task>
void ParallelFor(int count, int threads, const Task& task) {
  const int workers = std::clamp(threads, 1, std::max(count, 1));
  if (workers == 1) {
    for (int i = 0; i < count; ++i) task(i, 0);
    return;
  }
  std::atomic<int> next{0};
  std::atomic<bool> stop{false};
  std::exception_ptr error;
  std::mutex mutex;
  const auto work = [&](int worker) {
    try {
      for (int i = next++; i < count && !stop; i = next++) task(i, worker);
    } catch (...) {
      const std::lock_guard lock(mutex);
      if (!error) error = std::current_exception();
      stop = true;
    }
  };
  std::vector<std::thread> pool;
  pool.reserve(workers - 1);
  for (int w = 1; w < workers; ++w) pool.emplace_back(work, w);
  work(0);
  for (auto& thread : pool) thread.join();
  if (error) std::rethrow_exception(error);
}

}  // namespace millkit::numerics
