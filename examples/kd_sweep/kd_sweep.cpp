// A small what-if sweep (what `millkit sweep` runs from a study file): how the dynamic factor Kd
// of one spindle grows with the backlash of its hinge, on a grid of backlash values, on two
// threads.
//
//   kd_sweep datasets/scenes/mill5_bite.toml [LINK]     (LINK defaults to upper_spindle)
//
// Self-check: every case runs, and Kd at the largest backlash is above Kd without backlash (a
// gap that opens and closes hits harder; SPEC.md §2.5); otherwise exit 1. Bad input exits 2.
#include <cstdio>
#include <exception>
#include <iostream>
#include <string>
#include <vector>

#include "millkit/driveline/scene.h"
#include "millkit/driveline/scene_parameter.h"
#include "millkit/io/input_error.h"
#include "millkit/sweep/sample_plan.h"
#include "millkit/sweep/sweep_case.h"
#include "millkit/sweep/sweep_runner.h"

namespace dl = millkit::driveline;
namespace sw = millkit::sweep;

int main(int argc, char** argv) {
  if (argc != 2 && argc != 3) {
    std::cerr << "usage: kd_sweep SCENE.toml [LINK]\n";
    return 2;
  }
  try {
    const dl::Scene scene = dl::LoadScene(argv[1]);
    const std::string link = argc == 3 ? argv[2] : "upper_spindle";
    const int link_index = scene.LinkIndex(link);
    if (link_index < 0) throw millkit::InputError(std::string(argv[1]) + ": no link " + link);

    sw::SweepDimension backlash;
    backlash.parameter = dl::ParseSceneParameter(scene, link + ".backlash", "kd_sweep");
    backlash.lower = 0.0;
    backlash.upper = 0.04;  // rad
    backlash.points = 5;
    const std::vector<sw::SweepDimension> dimensions{backlash};
    const sw::CaseList cases = sw::GridCases(dimensions);

    sw::RunnerOptions runner;
    runner.threads = 2;
    sw::RunnerSummary summary;
    const std::vector<sw::CaseResult> results = sw::RunCases(
        sw::SceneCaseFunction(scene, {backlash.parameter}, sw::StudySimulationOptions()), cases,
        runner, &summary);
    std::cout << summary.BriefReport() << "\n";
    std::printf("%14s %10s %16s\n", (link + ".backlash").c_str(), "Kd", "peak torque N*m");
    for (size_t i = 0; i < cases.size(); ++i) {
      const sw::CaseResult& r = results[i];
      if (!r.success) {
        std::printf("%14.4g  failed: %s\n", cases[i][0], r.message.c_str());
        continue;
      }
      std::printf("%14.4g %10.4f %16.6g\n", cases[i][0], r.kd[link_index],
                  r.peak_torque_Nm[link_index]);
    }
    if (summary.failed > 0) {
      std::cerr << "kd_sweep: " << summary.failed << " case(s) failed\n";
      return 1;
    }
    if (!(results.back().kd[link_index] > results.front().kd[link_index])) {
      std::cerr << "kd_sweep: Kd did not grow with the backlash\n";
      return 1;
    }
    return 0;
  } catch (const millkit::InputError& e) {
    std::cerr << "kd_sweep: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "kd_sweep: " << e.what() << "\n";
    return 1;
  }
}
