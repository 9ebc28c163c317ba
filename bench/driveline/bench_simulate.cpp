// Work-precision benchmark of the drive-line solvers (issue 2). Not a test: it times.
//
// For one scene (default: the bundled five-mass bite) it runs, in the same process and run:
//  - the reference: CVODE at rtol 1e-14, against which every error below is measured, and which
//    the exact solver must match to 1e-9 of peak torque (the exit code says whether it did);
//  - CVODE (BDF) at rtol 1e-4 … 1e-14 and the exact solver, and the exact solver's speed-up over
//    CVODE at the tightest rtol (the only one that reaches the exact solver's error);
//  - the Kd-only path (keep_samples = false, estimate_error = false): runs per second on one core
//    and its dynamic factors against the reference's, reusing one Model and building a new Model
//    per run (what a sweep over scene parameters pays);
//  - the exact solver on the band-reduced model (--band Hz, default 20), for the speed gained and
//    the error it costs;
//  - SciPy solve_ivp (DOP853, LSODA) at several rtol through bench/driveline/scipy_simulate.py,
//    when /usr/bin/python3 has scipy.
// Error = max over samples and links of |m − m_ref| / max |m_ref| (relative to peak torque).
// Wall time = the minimum over repeated runs (the machine is shared: the minimum is the run least
// disturbed by other work), with the number of runs.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "millkit/driveline/simulation.h"
#include "millkit/io/csv.h"

using namespace millkit::driveline;

namespace {

std::string Format(const char* format, double value) {
  char text[64];
  std::snprintf(text, sizeof(text), format, value);
  return text;
}

double RelativeError(const SampleMatrix& value, const SampleMatrix& reference) {
  const double peak = reference.cwiseAbs().maxCoeff();
  return (value - reference).cwiseAbs().maxCoeff() / peak;
}

struct Timed {
  SimulationResult result;
  double seconds = 0.0;  // minimum over the runs
  int runs = 0;
};

// Repeats `run` for about budget_s (at least 3 times, at most 2000) and keeps the fastest.
template <typename Run>
double MinimumTime(const Run& run, double budget_s, int* runs) {
  double best = std::numeric_limits<double>::infinity();
  const auto begin = std::chrono::steady_clock::now();
  *runs = 0;
  do {
    const auto start = std::chrono::steady_clock::now();
    run();
    best = std::min(
        best, std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    ++*runs;
  } while ((*runs < 3 ||
            std::chrono::duration<double>(std::chrono::steady_clock::now() - begin).count() <
                budget_s) &&
           *runs < 2000);
  return best;
}

Timed Run(const Model& model, const SimulationOptions& options, double budget_s) {
  Timed timed;
  timed.seconds =
      MinimumTime([&] { timed.result = Simulate(model, options); }, budget_s, &timed.runs);
  return timed;
}

// max over links of |Kd − Kd_ref| / Kd_ref (links with a defined Kd).
double KdError(const std::vector<DynamicFactor>& value, const std::vector<DynamicFactor>& ref) {
  double worst = 0.0;
  for (size_t l = 0; l < ref.size(); ++l) {
    if (std::isnan(ref[l].kd)) continue;
    worst = std::max(worst, std::abs(value[l].kd - ref[l].kd) / ref[l].kd);
  }
  return worst;
}

}  // namespace

int main(int argc, char** argv) {
  std::string scene_path = std::string(MILLKIT_SOURCE_DIR) + "/datasets/scenes/mill5_bite.toml";
  std::string band_scene_path =
      std::string(MILLKIT_SOURCE_DIR) + "/datasets/scenes/mill5_stiff_motor.toml";
  double band = 20.0;
  bool scipy = true;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--band" && i + 1 < argc) {
      band = std::atof(argv[++i]);
    } else if (arg == "--no-scipy") {
      scipy = false;
    } else {
      scene_path = arg;
    }
  }
  const Model model(LoadScene(scene_path));
  std::printf("scene %s: %zu masses, %zu links, %d samples\n", scene_path.c_str(),
              model.scene().masses.size(), model.scene().links.size(), model.scene().SampleCount());

  SimulationOptions tight;
  tight.solver = SolverKind::kCvode;
  tight.rtol = 1e-14;
  const Timed reference = Run(model, tight, 1.0);
  SimulationOptions exact_options;
  const Timed exact = Run(model, exact_options, 2.0);
  const double cross = RelativeError(exact.result.link_torque_Nm, reference.result.link_torque_Nm);
  std::printf("reference: CVODE rtol 1e-14; the exact solver differs from it by %.2e of peak\n\n",
              cross);

  std::printf(
      "| solver | tolerance | events | steps | wall time ms (min of N) | N | "
      "max error / peak |\n");
  std::printf("|---|---|---|---|---|---|---|\n");
  std::printf("| exact | - | %ld | %ld | %.3f | %d | %.1e (own estimate %.1e) |\n",
              exact.result.summary.events, exact.result.summary.steps, exact.seconds * 1e3,
              exact.runs, cross, exact.result.summary.error_estimate);
  for (double rtol : {1e-4, 1e-6, 1e-8, 1e-10, 1e-12, 1e-14}) {
    SimulationOptions options;
    options.solver = SolverKind::kCvode;
    options.rtol = rtol;
    const Timed run = rtol == 1e-14 ? reference : Run(model, options, 1.0);
    std::printf("| CVODE BDF | rtol %.0e | %ld | %ld | %.3f | %d | %s |\n", rtol,
                run.result.summary.events, run.result.summary.steps, run.seconds * 1e3, run.runs,
                rtol == 1e-14 ? "reference"
                              : Format("%.1e", RelativeError(run.result.link_torque_Nm,
                                                             reference.result.link_torque_Nm))
                                    .c_str());
  }
  std::printf(
      "\nexact solver vs CVODE rtol 1e-14 (the CVODE run nearest its error): %.0fx faster\n",
      reference.seconds / exact.seconds);

  // The Kd-only path: peaks and Kd, no samples kept, no error estimate.
  SimulationOptions kd_options;
  kd_options.keep_samples = false;
  kd_options.estimate_error = false;
  // The two ways are timed alternately, so that both see the same load on the shared machine.
  Timed kd_run;
  SimulationResult fresh_result;
  double fresh_seconds = std::numeric_limits<double>::infinity();
  kd_run.seconds = std::numeric_limits<double>::infinity();
  auto seconds_since = [](std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  const auto kd_begin = std::chrono::steady_clock::now();
  while (kd_run.runs < 2000 && (kd_run.runs < 3 || seconds_since(kd_begin) < 4.0)) {
    auto start = std::chrono::steady_clock::now();
    kd_run.result = Simulate(model, kd_options);
    kd_run.seconds = std::min(kd_run.seconds, seconds_since(start));
    start = std::chrono::steady_clock::now();
    fresh_result = Simulate(Model(model.scene()), kd_options);
    fresh_seconds = std::min(fresh_seconds, seconds_since(start));
    ++kd_run.runs;
  }
  const int fresh_runs = kd_run.runs;
  const auto kd_reference = DynamicFactors(model, reference.result);
  const auto kd_full = DynamicFactors(model, exact.result);
  const auto kd_only = DynamicFactors(model, kd_run.result);
  bool identical = true;
  for (size_t l = 0; l < kd_full.size(); ++l) {
    identical = identical && (kd_only[l].kd == kd_full[l].kd ||
                              (std::isnan(kd_only[l].kd) && std::isnan(kd_full[l].kd)));
  }
  std::printf("\nKd-only path (keep_samples = false, estimate_error = false):\n\n");
  std::printf(
      "| run | wall time ms (min of N) | N | simulations/s | max Kd error vs reference |\n");
  std::printf("|---|---|---|---|---|\n");
  std::printf("| one Model, repeated | %.3f | %d | %.0f | %.1e |\n", kd_run.seconds * 1e3,
              kd_run.runs, 1.0 / kd_run.seconds, KdError(kd_only, kd_reference));
  std::printf("| new Model per run (sweep) | %.3f | %d | %.0f | %.1e |\n", fresh_seconds * 1e3,
              fresh_runs, 1.0 / fresh_seconds,
              KdError(DynamicFactors(model, fresh_result), kd_reference));
  std::printf("(Kd of the Kd-only path %s the full run's)\n\n",
              identical ? "is bit for bit" : "DIFFERS from");

  if (band > 0.0) {
    // Band-limited reduction on a line with a stiff motor shaft: the full model needs 20 kHz,
    // the reduced one may run at the five-mass scene's 5 kHz. Errors on the common 5 kHz grid,
    // for the links kept elastic and for the merged (rigid) link.
    const Model full(LoadScene(band_scene_path));
    Scene reduced_scene = full.scene();
    reduced_scene.band_Hz = band;
    reduced_scene.sample_rate_Hz = 5000.0;
    const Model reduced(reduced_scene);
    const int stride = static_cast<int>(full.scene().sample_rate_Hz / 5000.0);
    const Timed full_run = Run(full, exact_options, 1.0);
    const Timed run = Run(reduced, exact_options, 1.0);
    const SampleMatrix& fast = run.result.link_torque_Nm;
    SampleMatrix on_grid(fast.rows(), fast.cols());
    for (int k = 0; k < fast.rows(); ++k)
      on_grid.row(k) = full_run.result.link_torque_Nm.row(stride * k);
    const double peak = on_grid.cwiseAbs().maxCoeff();
    double kept = 0.0, merged = 0.0;
    for (int l = 0; l < fast.cols(); ++l) {
      const double e = (fast.col(l) - on_grid.col(l)).cwiseAbs().maxCoeff() / peak;
      (reduced.FlexibleIndexOf(l) < 0 ? merged : kept) =
          std::max(reduced.FlexibleIndexOf(l) < 0 ? merged : kept, e);
    }
    // Peak torque per link (what Kd is made of), relative to the full model's.
    double peak_error = 0.0;
    for (int l = 0; l < fast.cols(); ++l) {
      const double full_peak = full_run.result.link_torque_Nm.col(l).cwiseAbs().maxCoeff();
      peak_error =
          std::max(peak_error, std::abs(fast.col(l).cwiseAbs().maxCoeff() - full_peak) / full_peak);
    }
    std::printf("\nband-limited reduction on %s:\n\n", band_scene_path.c_str());
    std::printf(
        "| model | samples | events | wall time ms (min of N) | max error / peak, elastic "
        "links | merged link | peak torque per link |\n|---|---|---|---|---|---|---|\n");
    std::printf("| full, %.0f Hz | %d | %ld | %.3f | reference | reference | reference |\n",
                full.scene().sample_rate_Hz, full.scene().SampleCount(),
                full_run.result.summary.events, full_run.seconds * 1e3);
    std::printf("| band %.0f Hz, 5000 Hz | %d | %ld | %.3f | %.1e | %.1e | %.1e |\n", band,
                reduced_scene.SampleCount(), run.result.summary.events, run.seconds * 1e3, kept,
                merged, peak_error);
    for (const auto& line : reduced.reduction().report) std::printf("  (%s)\n", line.c_str());
    std::printf("\n");
  }
  if (scipy) {
    const std::string ref_csv = "/tmp/millkit_bench_reference.csv";
    {
      std::ofstream out(ref_csv);
      out.precision(17);
      out << "time";
      for (const auto& link : model.scene().links) out << "," << link.name;
      out << "\n";
      for (size_t k = 0; k < reference.result.time_s.size(); ++k) {
        out << reference.result.time_s[k];
        for (int j = 0; j < reference.result.link_torque_Nm.cols(); ++j) {
          out << "," << reference.result.link_torque_Nm(static_cast<int>(k), j);
        }
        out << "\n";
      }
    }
    const std::string command = "/usr/bin/python3 " + std::string(MILLKIT_SOURCE_DIR) +
                                "/bench/driveline/scipy_simulate.py '" + scene_path + "' " +
                                ref_csv;
    std::fflush(stdout);
    if (std::system(command.c_str()) != 0) std::printf("(SciPy run failed or not available)\n");
  }
  std::printf("\nexact vs CVODE(1e-14): %.2e of peak (limit 1e-9): %s\n", cross,
              cross <= 1e-9 ? "ok" : "MISMATCH");
  return cross <= 1e-9 && identical ? 0 : 1;
}
