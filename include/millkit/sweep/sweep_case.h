// One case of a what-if study (SPEC.md §5, issue 5): a scene with some named parameters set
// (millkit/driveline/scene_parameter.h), simulated once, reduced to the dynamic factor and peak
// torque of every link. Shared by the sweep runner and the coupling optimiser.
//
// SimulateCase is the only place where studies call the simulator, so that the switch to a
// samples-free run (SimulationOptions::keep_samples = false, peaks tracked by the solver) is one
// edit here.
#pragma once

#include <string>
#include <vector>

#include "millkit/driveline/scene_parameter.h"
#include "millkit/driveline/simulation.h"

namespace millkit::sweep {

// Per scene link (index as in Scene::links).
struct CaseResult {
  bool success = false;
  std::string message;                 // why the case failed; empty on success
  long events = 0;                     // phase switches of the run
  std::vector<double> kd;              // Kd = peak |m| / |m_s|; NaN where m_s = 0 (undefined)
  std::vector<double> peak_torque_Nm;  // max over the samples of |m(t)|
  std::vector<double> peak_time_s;
  std::vector<double> static_torque_Nm;  // m_s under the final loads (SPEC §2.5)
};

// Simulation settings for studies: the exact solver without its roundoff estimate (one matrix
// exponential per phase set less; the estimate is the benchmark's business, not each case's).
driveline::SimulationOptions StudySimulationOptions();

// `base` with values[i] set on parameters[i] (not validated; SimulateCase's model build does it).
driveline::Scene WithValues(const driveline::Scene& base,
                            const std::vector<driveline::SceneParameter>& parameters,
                            const std::vector<double>& values);

// Builds the model of `scene` and simulates it. Never throws for the case itself: a scene that is
// invalid at these values (e.g. a stiffness whose mode the sample rate cannot resolve) or a run
// that fails is reported with success = false and the message. Options must be valid.
CaseResult SimulateCase(const driveline::Scene& scene, const driveline::SimulationOptions& options);

}  // namespace millkit::sweep
