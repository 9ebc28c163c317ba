// Work-precision benchmark of the drive-line solvers (issue 2). Not a test: it times.
//
// For one scene (default: the bundled five-mass bite) it runs, in the same process and run:
//  - the reference: the exact solver, cross-checked against CVODE at rtol 1e-12;
//  - CVODE (BDF) at rtol 1e-4 … 1e-12 and the exact solver;
//  - the exact solver on the band-reduced model (--band Hz, default 20), for the speed gained and
//    the error it costs;
//  - SciPy solve_ivp (DOP853, LSODA) at several rtol through bench/driveline/scipy_simulate.py,
//    when /usr/bin/python3 has scipy.
// Error = max over samples and links of |m − m_ref| / max |m_ref| (relative to peak torque).
// Wall time = median of repeated runs. Exits non-zero when the exact solver misses 1e-9 against
// CVODE at 1e-12 (a mismatch, not a slowness).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "driveline/simulation.h"
#include "io/csv.h"

using namespace millkit::driveline;

namespace {

double RelativeError(const SampleMatrix& value, const SampleMatrix& reference) {
  const double peak = reference.cwiseAbs().maxCoeff();
  return (value - reference).cwiseAbs().maxCoeff() / peak;
}

struct Timed {
  SimulationResult result;
  double seconds = 0.0;
};

Timed Run(const Model& model, const SimulationOptions& options, double budget_s) {
  std::vector<double> times;
  Timed timed;
  const auto begin = std::chrono::steady_clock::now();
  do {
    const auto start = std::chrono::steady_clock::now();
    timed.result = Simulate(model, options);
    times.push_back(
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  } while (std::chrono::duration<double>(std::chrono::steady_clock::now() - begin).count() <
               budget_s &&
           times.size() < 200);
  std::sort(times.begin(), times.end());
  timed.seconds = times[times.size() / 2];
  return timed;
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
              model.scene().masses.size(), model.scene().links.size(),
              model.scene().SampleCount());

  SimulationOptions exact;
  const Timed reference = Run(model, exact, 2.0);
  SimulationOptions tight;
  tight.solver = SolverKind::kCvode;
  tight.rtol = 1e-14;
  const Timed cvode_tight = Run(model, tight, 0.5);
  const double cross = RelativeError(cvode_tight.result.link_torque_Nm,
                                     reference.result.link_torque_Nm);
  std::printf("reference: exact solver; CVODE rtol 1e-14 differs from it by %.2e of peak\n\n",
              cross);

  std::printf("| solver | tolerance | events | steps | wall time ms | max error / peak |\n");
  std::printf("|---|---|---|---|---|---|\n");
  std::printf("| exact | - | %ld | %ld | %.3f | %.1e (estimate %.1e) |\n",
              reference.result.summary.events, reference.result.summary.steps,
              reference.seconds * 1e3, cross, reference.result.summary.error_estimate);
  for (double rtol : {1e-4, 1e-6, 1e-8, 1e-10, 1e-12, 1e-14}) {
    SimulationOptions options;
    options.solver = SolverKind::kCvode;
    options.rtol = rtol;
    const Timed run = Run(model, options, 1.0);
    std::printf("| CVODE BDF | rtol %.0e | %ld | %ld | %.3f | %.1e |\n", rtol,
                run.result.summary.events, run.result.summary.steps, run.seconds * 1e3,
                RelativeError(run.result.link_torque_Nm, reference.result.link_torque_Nm));
  }
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
    const Timed full_run = Run(full, exact, 1.0);
    const Timed run = Run(reduced, exact, 1.0);
    const SampleMatrix& fast = run.result.link_torque_Nm;
    SampleMatrix on_grid(fast.rows(), fast.cols());
    for (int k = 0; k < fast.rows(); ++k) on_grid.row(k) = full_run.result.link_torque_Nm.row(stride * k);
    const double peak = on_grid.cwiseAbs().maxCoeff();
    double kept = 0.0, merged = 0.0;
    for (int l = 0; l < fast.cols(); ++l) {
      const double e = (fast.col(l) - on_grid.col(l)).cwiseAbs().maxCoeff() / peak;
      (reduced.FlexibleIndexOf(l) < 0 ? merged : kept) = std::max(
          reduced.FlexibleIndexOf(l) < 0 ? merged : kept, e);
    }
    // Peak torque per link (what Kd is made of), relative to the full model's.
    double peak_error = 0.0;
    for (int l = 0; l < fast.cols(); ++l) {
      const double full_peak = full_run.result.link_torque_Nm.col(l).cwiseAbs().maxCoeff();
      peak_error = std::max(peak_error,
                            std::abs(fast.col(l).cwiseAbs().maxCoeff() - full_peak) / full_peak);
    }
    std::printf("\nband-limited reduction on %s:\n\n", band_scene_path.c_str());
    std::printf("| model | samples | events | wall time ms | max error / peak, elastic links | "
                "merged link | peak torque per link |\n|---|---|---|---|---|---|---|\n");
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
  return cross <= 1e-9 ? 0 : 1;
}
