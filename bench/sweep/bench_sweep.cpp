// Sweep and coupling-optimiser benchmark (issue 5). Not a test: it times, and checks its answers.
//
// On the bundled five-mass bite scene and the study datasets/studies/mill5_lhs.toml (first
// --cases cases), in one run:
//  - bite simulations per second at 1 and 2 threads (min wall time over --repeats runs: the
//    machine is shared, the minimum is the least disturbed run), per core, and the parallel
//    efficiency rate(2) / (2 rate(1));
//  - where one case's time goes: model build, simulation, Kd;
//  - the error: Kd of --check cases against CVODE at rtol 1e-12 in the same run (max |ΔKd|);
//  - the coupling optimiser on datasets/studies/mill5_coupling.toml: evaluations, wall time.
// Under mpirun (a build with MILLKIT_WITH_MPI) it measures only the distributed throughput, one
// thread per rank, rows checked against a serial run on rank 0:
//   mpirun -np 1 bench_sweep; mpirun -np 2 bench_sweep
// Exits non-zero when the 1- and 2-thread rows differ or Kd misses CVODE by more than 1e-6
// (a wrong answer, not a slow one).
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "millkit/optimize/coupling/coupling_config.h"
#include "millkit/sweep/mpi_runner.h"
#include "millkit/sweep/sweep_config.h"
#include "millkit/sweep/sweep_runner.h"
#include "millkit/sweep/sweep_table.h"

using namespace millkit;
using Clock = std::chrono::steady_clock;

namespace {

constexpr double kKdTolerance = 1e-6;  // |Kd_exact − Kd_cvode(1e-12)|, both from samples

double Seconds(Clock::time_point since) {
  return std::chrono::duration<double>(Clock::now() - since).count();
}

// CPU time (user + system) of the whole process so far.
double CpuSeconds() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_utime.tv_sec + usage.ru_stime.tv_sec +
         1e-6 * (usage.ru_utime.tv_usec + usage.ru_stime.tv_usec);
}

struct Timing {
  double best_s = 1e300;
  double best_cpu_s = 1e300;  // CPU time of the least costly run: threads that wait for a core
                              // do not count, so it shows the code's own scaling on a busy machine
  std::string csv;
};

Timing TimeSweep(const driveline::Scene& scene, const sweep::SweepConfig& config,
                 const sweep::CaseList& cases, int threads, int repeats) {
  Timing timing;
  const auto evaluate =
      sweep::SceneCaseFunction(scene, config.Parameters(), sweep::StudySimulationOptions());
  sweep::RunnerOptions options;
  options.threads = threads;
  for (int r = 0; r < repeats; ++r) {
    sweep::RunnerSummary summary;
    const double cpu = CpuSeconds();
    const auto results = sweep::RunCases(evaluate, cases, options, &summary);
    timing.best_cpu_s = std::min(timing.best_cpu_s, CpuSeconds() - cpu);
    timing.best_s = std::min(timing.best_s, summary.wall_time_s);
    if (r == 0) timing.csv = sweep::FormatSweepCsv(scene, config, cases, results);
  }
  return timing;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string root = MILLKIT_SOURCE_DIR;
  int case_count = 1000, repeats = 5, check = 8;
  for (int i = 1; i < argc; i += 2) {
    const std::string arg = argv[i];
    if (arg == "--cases" && i + 1 < argc) {
      case_count = std::atoi(argv[i + 1]);
    } else if (arg == "--repeats" && i + 1 < argc) {
      repeats = std::atoi(argv[i + 1]);
    } else if (arg == "--check" && i + 1 < argc) {
      check = std::atoi(argv[i + 1]);
    } else {
      std::fprintf(stderr, "usage: %s [--cases N (1000)] [--repeats R (5)] [--check N (8)]\n",
                   argv[0]);
      return 2;
    }
  }
  const driveline::Scene scene = driveline::LoadScene(root + "/datasets/scenes/mill5_bite.toml");
  const sweep::SweepConfig config =
      sweep::LoadSweepConfig(root + "/datasets/studies/mill5_lhs.toml", scene);
  sweep::CaseList cases = config.Cases();
  cases.resize(std::min<size_t>(cases.size(), static_cast<size_t>(case_count)));
  const sweep::MpiSession mpi;
  if (std::getenv("OMPI_COMM_WORLD_SIZE") != nullptr) {
    const auto evaluate =
        sweep::SceneCaseFunction(scene, config.Parameters(), sweep::StudySimulationOptions());
    double best_s = 1e300;
    std::vector<sweep::CaseResult> results;
    for (int r = 0; r < repeats; ++r) {
      sweep::RunnerSummary summary;
      results = sweep::RunCasesDistributed(mpi, evaluate, cases, sweep::RunnerOptions{}, &summary);
      best_s = std::min(best_s, summary.wall_time_s);
    }
    if (!mpi.root()) return 0;
    const double rate = cases.size() / best_s;
    std::printf(
        "MPI ranks %d (1 thread each): %.0f simulations/s, %.0f per rank (%zu cases, "
        "min of %d)\n",
        mpi.size(), rate, rate / mpi.size(), cases.size(), repeats);
    const auto serial = sweep::RunCases(evaluate, cases, sweep::RunnerOptions{});
    const bool same = sweep::FormatSweepCsv(scene, config, cases, results) ==
                      sweep::FormatSweepCsv(scene, config, cases, serial);
    std::printf("rows %s the serial run's\n", same ? "identical to" : "DIFFER from");
    return same ? 0 : 1;
  }
  std::printf("scene %s, study %s: %zu cases, %d samples each, min of %d runs\n",
              scene.name.c_str(), "mill5_lhs.toml", cases.size(), scene.SampleCount(), repeats);
  int failures = 0;

  // Throughput and efficiency.
  const Timing one = TimeSweep(scene, config, cases, 1, repeats);
  const Timing two = TimeSweep(scene, config, cases, 2, repeats);
  const double rate1 = cases.size() / one.best_s, rate2 = cases.size() / two.best_s;
  std::printf("threads 1: %8.0f simulations/s (%.3f ms each)\n", rate1, 1e3 / rate1);
  std::printf("threads 2: %8.0f simulations/s, %.0f per core, efficiency %.2f\n", rate2,
              rate2 / 2.0, rate2 / (2.0 * rate1));
  std::printf(
      "CPU time per simulation: %.3f ms at 1 thread, %.3f ms at 2 threads (ratio %.2f: "
      "the efficiency two free cores would give)\n",
      1e3 * one.best_cpu_s / cases.size(), 1e3 * two.best_cpu_s / cases.size(),
      one.best_cpu_s / two.best_cpu_s);
  if (one.csv != two.csv) {
    std::printf("MISMATCH: rows differ between 1 and 2 threads\n");
    ++failures;
  }

  // Where one case's time goes (single thread, over the first 200 cases).
  {
    const auto parameters = config.Parameters();
    const auto options = sweep::StudySimulationOptions();
    double build = 0.0, simulate = 0.0, kd = 0.0;
    const size_t n = std::min<size_t>(cases.size(), 200);
    long events = 0;
    for (size_t c = 0; c < n; ++c) {
      auto t = Clock::now();
      const driveline::Model model(sweep::WithValues(scene, parameters, cases[c]));
      build += Seconds(t);
      t = Clock::now();
      const auto run = driveline::Simulate(model, options);
      simulate += Seconds(t);
      t = Clock::now();
      const auto factors = driveline::DynamicFactors(model, run);
      kd += Seconds(t);
      events += run.summary.events;
    }
    std::printf("per case: model build %.3f ms, simulation %.3f ms, Kd %.3f ms; %.1f events\n",
                1e3 * build / n, 1e3 * simulate / n, 1e3 * kd / n, static_cast<double>(events) / n);
  }

  // Error against CVODE at rtol 1e-12.
  {
    driveline::SimulationOptions cvode;
    cvode.solver = driveline::SolverKind::kCvode;
    cvode.rtol = 1e-12;
    double worst = 0.0, worst_relative = 0.0;
    const size_t stride = std::max<size_t>(1, cases.size() / std::max(check, 1));
    int compared = 0;
    for (size_t c = 0; c < cases.size() && compared < check; c += stride, ++compared) {
      const auto at = sweep::WithValues(scene, config.Parameters(), cases[c]);
      const auto exact = sweep::SimulateCase(at, sweep::StudySimulationOptions());
      const auto reference = sweep::SimulateCase(at, cvode);
      if (!exact.success || !reference.success) {
        std::printf("case %zu failed: %s %s\n", c, exact.message.c_str(),
                    reference.message.c_str());
        ++failures;
        continue;
      }
      for (size_t l = 0; l < exact.kd.size(); ++l) {
        const double d = std::abs(exact.kd[l] - reference.kd[l]);
        worst = std::max(worst, d);
        worst_relative = std::max(worst_relative, d / reference.kd[l]);
      }
    }
    std::printf(
        "Kd error vs CVODE rtol 1e-12 over %d cases x %zu links: max |dKd| %.2e "
        "(relative %.2e)\n",
        compared, scene.links.size(), worst, worst_relative);
    if (!(worst <= kKdTolerance)) {
      std::printf("MISMATCH: Kd differs from CVODE by more than %.0e\n", kKdTolerance);
      ++failures;
    }
  }

  // The coupling optimiser.
  {
    const auto study =
        coupling::LoadCouplingStudy(root + "/datasets/studies/mill5_coupling.toml", scene);
    double best_s = 1e300;
    coupling::CouplingResult result;
    for (int r = 0; r < std::max(1, repeats / 2); ++r) {
      result = coupling::OptimizeCoupling(scene, study.problem, study.options);
      best_s = std::min(best_s, result.summary.wall_time_s);
    }
    const auto& s = result.summary;
    std::printf(
        "coupling: %d + %d evaluations (%d simulations), %.3f s (min), Kd_max %.4f "
        "(scene as given %.4f), from %s\n",
        s.global_evaluations, s.local_evaluations, s.simulations, best_s, result.best.kd_max,
        result.scene ? result.scene->kd_max : NAN, s.chosen_from.c_str());
    if (!s.found) {
      std::printf("coupling: no feasible point found\n");
      ++failures;
    }
  }
  return failures == 0 ? 0 : 1;
}
