// The hybrid event loop every drive-line solver runs (internal to src/driveline, not installed
// API). RunHybrid owns what does not depend on how a phase set is integrated: the output times,
// the input breakpoints, the recorder, the event policy (classification of the new phases, events
// that do not advance time and the escape from a degenerate switch, max_events) and the summary.
// A solver supplies a ModeIntegrator: it advances the state within one phase set, stopping at
// the first switching event, and knows how to restart after one.
//
// The loop, one leg at a time: a leg runs from the current time to the next output time, or to
// an input breakpoint before it (one within 4 ulps of an output time is taken at that output
// time), or to the end of an escape. A leg ends where it was aimed or at an event. At an event
// the model classifies the phases from the state and its derivatives there, with the crossed
// surfaces' new sides known; events that come within 64 ulps of the previous stop, or within
// 1e-6 of the time scale of it (a contact chattering across a surface), more than 64
// times in a row are a degenerate switch: the integrator steps on blind to the surfaces that
// chattered for 1e-9, then 1e-6, then 1e-3 of the time scale (as CVODE is blind to a root
// function that starts at zero), and a fourth time the run ends with "events do not advance
// time". At a breakpoint the forcing takes its right limit; at an output time the sample is
// recorded.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <string>
#include <vector>

#include "driveline/output_recorder.h"
#include "millkit/driveline/model.h"
#include "millkit/driveline/simulation.h"

namespace millkit::driveline {

// Where one leg of the run is aimed (times in s).
struct Leg {
  double target = 0.0;       // the leg ends here unless an event comes first
  double output_time = 0.0;  // the next output time (>= target)
  bool at_output = false;    // target is the output time
  bool from_output = false;  // the leg starts exactly at the previous output time
  bool at_breakpoint = false;
  double breakpoint = 0.0;  // its time, when at_breakpoint (target may be snapped onto output)
  // The next breakpoint not yet passed, or the last output time: an integrator that steps past
  // its target and interpolates back (CVODE) must not step past this.
  double next_stop = 0.0;
  // While escaping a degenerate switch: per model surface, 1 for a surface not to watch.
  const std::vector<char>* ignored = nullptr;
};

// How a leg ended.
struct LegEnd {
  enum class Kind { kReached, kEvent, kFailed };
  Kind kind = Kind::kReached;
  double t = 0.0;        // the time reached: the target, or the event
  double elapsed = 0.0;  // the leg's length to that time, as the integrator computed it
  std::vector<Model::KnownSide> crossed;  // kEvent: each crossed surface's new side
  std::string message;                    // kFailed: why
};

class ModeIntegrator {
 public:
  virtual ~ModeIntegrator() = default;
  ModeIntegrator() = default;
  ModeIntegrator(const ModeIntegrator&) = delete;
  ModeIntegrator& operator=(const ModeIntegrator&) = delete;

  // Time scale of "events that do not advance time" and of the escapes (about one output step).
  virtual double time_scale() const = 0;
  // Starts at t = 0 from the augmented state z0 in `phases`; summary stays valid for the run
  // (the integrator adds its counts to it). Returns a failure message, or empty.
  virtual std::string Start(const Eigen::VectorXd& z0, const Phases& phases,
                            SimulationSummary* summary) = 0;
  // Advances from t along the leg within the current phases.
  virtual void Advance(double t, const Leg& leg, LegEnd* end) = 0;
  // After an event: the augmented state there and its time derivatives z', z'', ... in the
  // phases before the event (for Model::Classify; an order may be left empty).
  virtual void EventMotion(Eigen::VectorXd* z, std::vector<Eigen::VectorXd>* derivatives) = 0;
  // Continues from the event state, at time t, in the new phases.
  virtual void Switch(const Phases& phases, double t) = 0;
  // The forcing takes its right limit at breakpoint time `breakpoint`; the state is at time t.
  virtual void ApplyBreakpoint(double breakpoint, double t) = 0;
  // Records output sample k (output time t_output) from the current state.
  virtual void Record(OutputRecorder* recorder, int k, double t_output) = 0;
  // At the end of the run (also after a failure): final counts into the summary.
  virtual void Finish(SimulationSummary* summary) = 0;
  // The augmented state now (after a leg that reached its target, or a breakpoint); for an
  // observer (sensitivity.cpp). An integrator that cannot tell leaves z empty.
  virtual void State(Eigen::VectorXd* z) const { z->resize(0); }
};

// What a run did, stop by stop, for a pass that follows it (the forward sensitivities,
// sensitivity.cpp). Every leg that does not fail ends in LegEnded (its length and end state);
// an event then calls Switched, a breakpoint BreakpointApplied, an output time Recorded.
class HybridObserver {
 public:
  virtual ~HybridObserver() = default;
  HybridObserver() = default;
  HybridObserver(const HybridObserver&) = delete;
  HybridObserver& operator=(const HybridObserver&) = delete;

  virtual void Started(const Eigen::VectorXd& z0, const Phases& phases) = 0;
  // A leg of `elapsed` s in `phases` ended at state z; `blind`: it ran blind to some surfaces
  // (escaping a degenerate switch), so a crossing may have been stepped over.
  virtual void LegEnded(double elapsed, const Phases& phases, const Eigen::VectorXd& z,
                        bool blind) = 0;
  // An event at the state of the last LegEnded: the phases before and after, the crossed surfaces.
  virtual void Switched(const Phases& before, const Phases& after,
                        const std::vector<Model::KnownSide>& crossed) = 0;
  // The forcing took its right limit at `breakpoint`: z is the state after.
  virtual void BreakpointApplied(double breakpoint, const Eigen::VectorXd& z) = 0;
  // Output sample k was recorded in `phases`.
  virtual void Recorded(int k, const Phases& phases) = 0;
};

// Runs the hybrid loop with `integrator`; the summary's solver is `solver`. Validate the options
// first. An exception from options.sample_sink or options.progress propagates.
// `observer`, when given, is told every stop.
SimulationResult RunHybrid(const Model& model, const SimulationOptions& options, const char* solver,
                           ModeIntegrator* integrator, HybridObserver* observer = nullptr);

// The integrators, one per SolverKind (their sources).
std::unique_ptr<ModeIntegrator> MakeExactIntegrator(const Model& model,
                                                    const SimulationOptions& options);
// The exact solver's cached step length and the scale of each augmented component it steps in
// (exact_solver.cpp).
double ExactStepLength(const Model& model, const SimulationOptions& options);
Eigen::VectorXd ExactScale(const Model& model, double step);
std::unique_ptr<ModeIntegrator> MakeCvodeIntegrator(const Model& model,
                                                    const SimulationOptions& options);

}  // namespace millkit::driveline
