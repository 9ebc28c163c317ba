// Simulate a drive-line scene and print every link's dynamic factor Kd (SPEC.md §2.5), what
// `millkit simulate SCENE --kd-only` prints.
//
//   simulate_kd datasets/scenes/mill5_bite.toml
//
// Self-check: the run succeeds and the exact solver's error estimate is within its target
// (kExactErrorTarget); otherwise exit 1. Bad input (a missing file, an invalid scene) exits 2.
#include <exception>
#include <iostream>

#include "millkit/driveline/model.h"
#include "millkit/driveline/scene.h"
#include "millkit/driveline/simulation.h"
#include "millkit/io/input_error.h"
#include "millkit/version.h"

namespace dl = millkit::driveline;

int main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: simulate_kd SCENE.toml\n";
    return 2;
  }
  try {
    const dl::Model model(dl::LoadScene(argv[1]));
    dl::SimulationOptions options;  // the exact solver, the scene's own sample grid
    options.keep_samples = false;   // Kd needs only each link's peak torque
    const dl::SimulationResult result = dl::Simulate(model, options);
    std::cout << "MillKit " << MILLKIT_VERSION_STRING << ", scene: " << model.scene().name << "\n"
              << result.summary.BriefReport() << "\n";
    if (!result.summary.success) {
      std::cerr << "simulate_kd: the simulation failed: " << result.summary.message << "\n";
      return 1;
    }
    std::cout << dl::FormatDynamicFactorTable(dl::DynamicFactors(model, result));
    if (!(result.summary.error_estimate <= dl::kExactErrorTarget)) {
      std::cerr << "simulate_kd: error estimate " << result.summary.error_estimate
                << " above the target " << dl::kExactErrorTarget << "\n";
      return 1;
    }
    return 0;
  } catch (const millkit::InputError& e) {
    std::cerr << "simulate_kd: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "simulate_kd: " << e.what() << "\n";
    return 1;
  }
}
