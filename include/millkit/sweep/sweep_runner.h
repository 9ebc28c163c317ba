// Runs the cases of a study on a pool of std::threads (issue 5). Cases are independent; each
// worker takes the next unstarted case and writes its result into that case's slot, so the
// results come back in case order and are bitwise the same for any number of threads (every case
// runs the same code on the same inputs; nothing is shared between cases).
//
// Progress: with `progress` set, a line "sweep: 120/1000 cases, 2 failed, 850 cases/s, ~1.0 s
// left" is rewritten on that stream about twice a second, starting after the first second (short
// runs print nothing), and ended with a newline.
#pragma once

#include <functional>
#include <ostream>
#include <string>
#include <vector>

#include "millkit/sweep/sample_plan.h"
#include "millkit/sweep/sweep_case.h"

namespace millkit::sweep {

struct RunnerOptions {
  int threads = 1;
  std::ostream* progress = nullptr;  // none when null
  std::string label = "sweep";       // first word of the progress line

  // Throws InputError unless 1 <= threads <= kMaxThreads.
  void Validate() const;
};
inline constexpr int kMaxThreads = 256;

struct RunnerSummary {
  int cases = 0;
  int failed = 0;
  int threads = 0;
  double wall_time_s = 0.0;
  std::string BriefReport() const;  // "1000 cases (2 failed) on 2 threads in 0.52 s, 1923 cases/s"
};

// Evaluates one case; must be safe to call from several threads at once.
using CaseFunction = std::function<CaseResult(const std::vector<double>& values)>;

// Runs every case. An exception other than the case's own failure (which the CaseFunction
// reports in its result) stops the pool and is rethrown here after every thread has joined.
std::vector<CaseResult> RunCases(const CaseFunction& evaluate, const CaseList& cases,
                                 const RunnerOptions& options, RunnerSummary* summary = nullptr);

// The usual CaseFunction: `base` with the values set on `parameters`, then SimulateCase.
CaseFunction SceneCaseFunction(const driveline::Scene& base,
                               std::vector<driveline::SceneParameter> parameters,
                               const driveline::SimulationOptions& options);

}  // namespace millkit::sweep
