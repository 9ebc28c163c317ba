#include "millkit/sweep/sweep_case.h"

#include "millkit/io/input_error.h"

namespace millkit::sweep {

driveline::SimulationOptions StudySimulationOptions() {
  driveline::SimulationOptions options;
  options.solver = driveline::SolverKind::kExact;
  options.estimate_error = false;
  // Kd needs only each link's peak |torque|, which every result carries.
  options.keep_samples = false;
  return options;
}

driveline::Scene WithValues(const driveline::Scene& base,
                            const std::vector<driveline::SceneParameter>& parameters,
                            const std::vector<double>& values) {
  driveline::Scene scene = base;
  for (size_t i = 0; i < parameters.size(); ++i) parameters[i].Set(values[i], &scene);
  return scene;
}

CaseResult SimulateCase(const driveline::Scene& scene,
                        const driveline::SimulationOptions& options) {
  CaseResult result;
  try {
    const driveline::Model model(scene);
    const driveline::SimulationResult run = driveline::Simulate(model, options);
    result.events = run.summary.events;
    if (!run.summary.success) {
      result.message = run.summary.message;
      return result;
    }
    for (const auto& f : driveline::DynamicFactors(model, run)) {
      result.kd.push_back(f.kd);
      result.peak_torque_Nm.push_back(f.peak_torque_Nm);
      result.peak_time_s.push_back(f.peak_time_s);
      result.static_torque_Nm.push_back(f.static_torque_Nm);
    }
    result.success = true;
  } catch (const InputError& e) {
    result.message = e.what();
  }
  return result;
}

}  // namespace millkit::sweep
