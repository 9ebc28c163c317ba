#include "millkit/driveline/simulation.h"

#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <sstream>
#include <stdexcept>

#include "driveline/hybrid_driver.h"
#include "millkit/io/input_error.h"
#include "millkit/io/number_format.h"

namespace millkit::driveline {

void SimulationOptions::Validate() const {
  if (!(rtol >= kMinRtol && rtol <= 1e-2)) {
    throw InputError::Option("SimulationOptions", "rtol",
                             "must lie in [1e-14, 1e-2] (got " + FormatNumber(rtol) + ")");
  }
  if (atol && !(*atol > 0.0 && *atol <= 1.0)) {
    throw InputError::Option("SimulationOptions", "atol",
                             "must lie in (0, 1], a fraction of each state's typical magnitude "
                             "(got " +
                                 FormatNumber(*atol) + ")");
  }
  if (max_steps < 1) throw InputError::Option("SimulationOptions", "max_steps", "must be >= 1");
  if (max_events < 0) throw InputError::Option("SimulationOptions", "max_events", "must be >= 0");
  if (!output_times) return;
  const std::vector<double>& times = *output_times;
  if (times.empty()) throw InputError("option output_times: must not be empty");
  for (size_t i = 0; i < times.size(); ++i) {
    const bool finite = std::isfinite(times[i]);
    if (finite && (i == 0 ? times[0] >= 0.0 : times[i] > times[i - 1])) continue;
    // Only a bad time builds its message: a fit checks thousands of output times per run.
    const std::string at = "option output_times[" + std::to_string(i) + "] = ";
    if (!finite) {
      throw InputError(at + FormatNumber(times[i]) + ": must be finite");
    }
    if (i == 0 && times[0] < 0.0) {
      throw InputError(at + FormatNumber(times[0]) + ": the first output time must be >= 0");
    }
    if (i > 0 && !(times[i] > times[i - 1])) {
      throw InputError(at + FormatNumber(times[i]) +
                       ": output times must be strictly increasing (output_times[" +
                       std::to_string(i - 1) + "] = " + FormatNumber(times[i - 1]) + ")");
    }
  }
}

void SimulationOptions::Validate(const Scene& scene) const {
  Validate();
  if (output_times && output_times->back() > scene.duration_s) {
    throw InputError("option output_times: the last output time " +
                     FormatNumber(output_times->back()) + " s must be <= the scene duration " +
                     FormatNumber(scene.duration_s) + " s ([scene] duration of " +
                     (scene.file.empty() ? std::string("<scene>") : scene.file) + ")");
  }
}

std::vector<double> OutputTimes(const Scene& scene, const SimulationOptions& options) {
  if (options.output_times) return *options.output_times;
  const int samples = scene.SampleCount();
  const double h = 1.0 / scene.sample_rate_Hz;
  std::vector<double> times(samples);
  for (int k = 0; k < samples; ++k) times[k] = k * h;
  return times;
}

std::string SimulationSummary::BriefReport() const {
  std::ostringstream s;
  s << solver << ": " << (success ? "success" : "FAILED") << ", " << events << " events, " << steps
    << " steps";
  if (rhs_evaluations > 0) s << ", " << rhs_evaluations << " rhs";
  s << ", " << wall_time_s * 1e3 << " ms, " << error_kind << " " << error_estimate;
  if (!success) s << ": " << message;
  return s.str();
}

namespace {

struct SolverEntry {
  SolverInfo info;
  std::unique_ptr<ModeIntegrator> (*make)(const Model&, const SimulationOptions&);
};

const std::vector<SolverEntry>& Registry() {
  static const std::vector<SolverEntry> registry = {
      {{SolverKind::kExact, "exact",
        "event-exact piecewise-linear propagation, error estimated per run (default)"},
       MakeExactIntegrator},
      {{SolverKind::kCvode, "cvode", "SUNDIALS CVODES (BDF) with root finding at the events"},
       MakeCvodeIntegrator},
  };
  return registry;
}

const SolverEntry& EntryOf(SolverKind kind) {
  for (const SolverEntry& entry : Registry()) {
    if (entry.info.kind == kind) return entry;
  }
  throw std::logic_error("solver kind not in the registry");
}

SimulationResult Run(const Model& model, const SimulationOptions& options, SolverKind kind) {
  options.Validate(model.scene());
  const SolverEntry& entry = EntryOf(kind);
  const std::unique_ptr<ModeIntegrator> integrator = entry.make(model, options);
  return RunHybrid(model, options, entry.info.name, integrator.get());
}

}  // namespace

const std::vector<SolverInfo>& Solvers() {
  static const std::vector<SolverInfo> solvers = [] {
    std::vector<SolverInfo> infos;
    for (const SolverEntry& entry : Registry()) infos.push_back(entry.info);
    return infos;
  }();
  return solvers;
}

const SolverInfo& SolverOf(SolverKind kind) {
  for (const SolverInfo& info : Solvers()) {
    if (info.kind == kind) return info;
  }
  throw std::logic_error("solver kind not in the registry");
}

const SolverInfo* FindSolver(std::string_view name) {
  for (const SolverInfo& info : Solvers()) {
    if (name == info.name) return &info;
  }
  return nullptr;
}

std::string SolverNames() {
  std::string names;
  for (const SolverInfo& info : Solvers()) {
    if (!names.empty()) names += ", ";
    names += info.name;
  }
  return names;
}

SimulationResult Simulate(const Model& model, const SimulationOptions& options) {
  return Run(model, options, options.solver);
}

SimulationResult SimulateExact(const Model& model, const SimulationOptions& options) {
  return Run(model, options, SolverKind::kExact);
}

SimulationResult SimulateCvode(const Model& model, const SimulationOptions& options) {
  return Run(model, options, SolverKind::kCvode);
}

SimulationResult SimulateCvodeChecked(const Model& model, const SimulationOptions& options) {
  // At the tolerance floor there is no tighter run: the figure stays the requested tolerance.
  if (options.rtol / 10.0 < kMinRtol) return SimulateCvode(model, options);
  SimulationOptions finer = options;
  finer.solver = SolverKind::kCvode;
  finer.rtol = options.rtol / 10.0;
  if (options.atol) finer.atol = *options.atol / 10.0;
  finer.keep_samples = true;  // the check compares every sample
  finer.sample_sink = nullptr;
  SimulationOptions first = finer;
  first.rtol = options.rtol;
  first.atol = options.atol;
  first.sample_sink = options.sample_sink;
  // The two runs share the progress range: the first half, then the second.
  if (options.progress) {
    first.progress = [&options](double fraction) { options.progress(0.5 * fraction); };
    finer.progress = [&options](double fraction) { options.progress(0.5 + 0.5 * fraction); };
  }
  SimulationResult result = SimulateCvode(model, first);
  if (!result.summary.success) return result;
  const SimulationResult reference = SimulateCvode(model, finer);
  if (!reference.summary.success) {
    result.summary.error_kind =
        "error vs rtol/10 (the check run failed: " + reference.summary.message + ")";
    result.summary.error_estimate = std::numeric_limits<double>::quiet_NaN();
    return result;
  }
  const double peak = reference.link_torque_Nm.size() > 0
                          ? reference.link_torque_Nm.cwiseAbs().maxCoeff()
                          : reference.mass_speed_rad_per_s.cwiseAbs().maxCoeff();
  const SampleMatrix& a =
      result.link_torque_Nm.size() > 0 ? result.link_torque_Nm : result.mass_speed_rad_per_s;
  const SampleMatrix& b = reference.link_torque_Nm.size() > 0 ? reference.link_torque_Nm
                                                              : reference.mass_speed_rad_per_s;
  result.summary.error_kind = result.link_torque_Nm.size() > 0 ? "error vs rtol/10 (of peak torque)"
                                                               : "error vs rtol/10 (of peak speed)";
  result.summary.error_estimate = peak > 0.0 ? (a - b).cwiseAbs().maxCoeff() / peak : 0.0;
  result.summary.wall_time_s += reference.summary.wall_time_s;
  return result;
}

std::vector<DynamicFactor> DynamicFactors(const Model& model, const SimulationResult& result) {
  const Scene& scene = model.scene();
  const std::vector<double> static_torque = StaticLinkTorques(scene);  // each link's units
  // "Zero to roundoff" against the loads, compared on the reference shaft.
  const Scene& reduced = model.reduced_scene();
  double load_scale = 0.0;
  for (const auto& source : reduced.torques) {
    load_scale += std::abs(source.ValueAt(reduced.duration_s));
  }
  std::vector<DynamicFactor> factors;
  for (size_t l = 0; l < scene.links.size(); ++l) {
    DynamicFactor f;
    f.link = scene.links[l].name;
    f.static_torque_Nm = static_torque[l];
    if (result.peak_abs_torque_Nm.size() == scene.links.size()) {
      f.peak_torque_Nm = result.peak_abs_torque_Nm[l];
      f.peak_time_s = result.peak_time_s[l];
    } else {
      const auto column = result.link_torque_Nm.col(static_cast<int>(l));
      Eigen::Index at = 0;
      if (column.size() > 0) f.peak_torque_Nm = column.cwiseAbs().maxCoeff(&at);
      f.peak_time_s = result.time_s.empty() ? 0.0 : result.time_s[at];
    }
    const bool defined = std::abs(f.static_torque_Nm) * model.shaft_factors().link[l] >
                         1e-12 * std::max(load_scale, 1e-300);
    f.kd = defined ? f.peak_torque_Nm / std::abs(f.static_torque_Nm)
                   : std::numeric_limits<double>::quiet_NaN();
    factors.push_back(f);
  }
  return factors;
}

std::string FormatDynamicFactorTable(const std::vector<DynamicFactor>& factors) {
  std::ostringstream s;
  char line[256];
  std::snprintf(line, sizeof(line), "%-20s %16s %10s %16s %8s\n", "link", "peak |m| N*m", "at s",
                "static m_s N*m", "Kd");
  s << line;
  for (const auto& f : factors) {
    char kd[32];
    if (std::isnan(f.kd)) {
      std::snprintf(kd, sizeof(kd), "%8s", "n/a");
    } else {
      std::snprintf(kd, sizeof(kd), "%8.3f", f.kd);
    }
    std::snprintf(line, sizeof(line), "%-20s %16.1f %10.5f %16.1f %s\n", f.link.c_str(),
                  f.peak_torque_Nm, f.peak_time_s, f.static_torque_Nm, kd);
    s << line;
  }
  return s.str();
}

}  // namespace millkit::driveline
