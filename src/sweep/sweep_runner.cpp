#include "millkit/sweep/sweep_runner.h"

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <exception>
#include <mutex>
#include <thread>

#include "millkit/io/input_error.h"

namespace millkit::sweep {
namespace {

using Clock = std::chrono::steady_clock;
constexpr auto kProgressDelay = std::chrono::seconds(1);
constexpr auto kProgressInterval = std::chrono::milliseconds(500);

double Seconds(Clock::duration d) { return std::chrono::duration<double>(d).count(); }

void PrintProgress(std::ostream& out, const std::string& label, int done, int total, int failed,
                   double elapsed_s) {
  char line[160];
  const double rate = elapsed_s > 0.0 ? done / elapsed_s : 0.0;
  const double left = rate > 0.0 ? (total - done) / rate : 0.0;
  std::snprintf(line, sizeof(line), "\r%s: %d/%d cases, %d failed, %.0f cases/s, ~%.1f s left   ",
                label.c_str(), done, total, failed, rate, left);
  out << line << std::flush;
}

}  // namespace

void RunnerOptions::Validate() const {
  if (threads < 1 || threads > kMaxThreads) {
    throw InputError::Option("RunnerOptions", "threads",
                             "must lie in [1, " + std::to_string(kMaxThreads) + "] (got " +
                                 std::to_string(threads) + ")");
  }
}

std::string RunnerSummary::BriefReport() const {
  char line[200];
  std::snprintf(line, sizeof(line), "%d cases (%d failed) on %d thread%s in %.3g s, %.0f cases/s",
                cases, failed, threads, threads == 1 ? "" : "s", wall_time_s,
                wall_time_s > 0.0 ? cases / wall_time_s : 0.0);
  return line;
}

std::vector<CaseResult> RunCases(const CaseFunction& evaluate, const CaseList& cases,
                                 const RunnerOptions& options, RunnerSummary* summary) {
  options.Validate();
  const int total = static_cast<int>(cases.size());
  const int threads = std::max(1, std::min(options.threads, total));
  std::vector<CaseResult> results(cases.size());
  std::atomic<int> next{0}, done{0}, failed{0};
  std::atomic<bool> stop{false};
  std::exception_ptr error;
  std::mutex mutex;
  std::condition_variable finished;
  int running = threads;

  auto work = [&] {
    try {
      for (int i = next++; i < total && !stop; i = next++) {
        results[i] = evaluate(cases[i]);
        if (!results[i].success) ++failed;
        ++done;
      }
    } catch (...) {
      std::lock_guard lock(mutex);
      if (!error) error = std::current_exception();
      stop = true;
    }
    std::lock_guard lock(mutex);
    --running;
    finished.notify_all();
  };

  const auto started = Clock::now();
  std::vector<std::thread> pool;
  pool.reserve(threads);
  for (int t = 0; t < threads; ++t) pool.emplace_back(work);
  bool printed = false;
  {
    std::unique_lock lock(mutex);
    auto wake = started + kProgressDelay;
    while (running > 0) {
      if (finished.wait_until(lock, wake, [&] { return running == 0; })) break;
      if (options.progress != nullptr) {
        PrintProgress(*options.progress, options.label, done, total, failed,
                      Seconds(Clock::now() - started));
        printed = true;
      }
      wake = Clock::now() + kProgressInterval;
    }
  }
  for (auto& thread : pool) thread.join();
  const double wall = Seconds(Clock::now() - started);
  if (printed) {
    PrintProgress(*options.progress, options.label, done, total, failed, wall);
    *options.progress << "\n";
  }
  if (error) std::rethrow_exception(error);
  if (summary != nullptr) *summary = {total, failed.load(), threads, wall};
  return results;
}

CaseFunction SceneCaseFunction(const driveline::Scene& base,
                               std::vector<driveline::SceneParameter> parameters,
                               const driveline::SimulationOptions& options) {
  options.Validate();
  return [base, parameters = std::move(parameters), options](const std::vector<double>& values) {
    return SimulateCase(WithValues(base, parameters, values), options);
  };
}

}  // namespace millkit::sweep
