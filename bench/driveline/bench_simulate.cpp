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
    // Band-limited reduction on a line with a stiff motor shaft (its own full-model reference).
    const Model full(LoadScene(band_scene_path));
    Scene reduced_scene = full.scene();
    reduced_scene.band_Hz = band;
    const Model reduced(reduced_scene);
    const Timed full_run = Run(full, exact, 1.0);
    const Timed run = Run(reduced, exact, 1.0);
    std::printf("\nband-limited reduction on %s (%d samples):\n\n", band_scene_path.c_str(),
                full.scene().SampleCount());
    std::printf("| model | events | steps | wall time ms | max error / peak |\n|---|---|---|---|---|\n");
    std::printf("| full | %ld | %ld | %.3f | reference |\n", full_run.result.summary.events,
                full_run.result.summary.steps, full_run.seconds * 1e3);
    std::printf("| band %.0f Hz, %zu merged | %ld | %ld | %.3f | %.1e |\n", band,
                reduced.reduction().report.size(), run.result.summary.events,
                run.result.summary.steps, run.seconds * 1e3,
                RelativeError(run.result.link_torque_Nm, full_run.result.link_torque_Nm));
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
