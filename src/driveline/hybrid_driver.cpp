// The hybrid event loop of every drive-line solver; see hybrid_driver.h.
#include "driveline/hybrid_driver.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

namespace millkit::driveline {
namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();
// An event within this many ulps of the previous stop (of time and of the time scale), or within
// kChatterFraction of the time scale, does not advance time; more than kMaxStalledEvents of them
// in a row are a degenerate switch. The fraction catches a contact that chatters across a
// surface on both of whose sides the motion points back at it: its events advance time by more
// than ulps. Found on a limited-law link at the corner ψ = b/2, ψ' = 0 under a heavy damper
// (+2c and +free 4e-13 s apart, where 1e-6 of a sample step is 6e-12 s: a million events
// advanced time by 2e-7 s), which the corner rule (kLinkSideFromMotion) has since mended; the
// guard stays for any other. No resolved motion switches that fast: the scene rule puts 4
// samples in the fastest period.
constexpr double kStallUlps = 64.0;
constexpr double kChatterFraction = 1e-6;
constexpr int kMaxStalledEvents = 64;
// Escapes from a degenerate switch, each blind to the chattering surfaces for this fraction of
// the time scale, before the run gives up with "events do not advance time".
constexpr int kMaxEscapes = 3;
constexpr double kEscapeFraction[kMaxEscapes] = {1e-9, 1e-6, 1e-3};

}  // namespace

SimulationResult RunHybrid(const Model& model, const SimulationOptions& options, const char* solver,
                           ModeIntegrator* integrator, HybridObserver* observer) {
  const auto started = std::chrono::steady_clock::now();
  SimulationResult result;
  SimulationSummary& summary = result.summary;
  summary.solver = solver;
  summary.reduction = model.reduction().report;
  OutputRecorder recorder(model, options, &result);
  const OutputGrid& times = recorder.times();
  const int samples = recorder.size();

  Eigen::VectorXd z0 = model.InitialState();
  if (options.initial_state) {
    z0.head(model.state_size()) = options.initial_state->head(model.state_size());
  }
  Phases phases = options.initial_state ? model.InitialPhases(z0) : model.InitialPhases();
  summary.message = integrator->Start(z0, phases, &summary);
  if (observer != nullptr && summary.message.empty()) observer->Started(z0, phases);
  const double h = integrator->time_scale();
  // Breakpoints: the input slopes change (ramp ends, steps). Taken from the reduced scene, whose
  // inputs the model integrates.
  const std::vector<double> breakpoints = model.reduced_scene().InputBreakpoints();
  size_t next_breakpoint = 0;

  double t = 0.0;
  bool from_output = true;  // t is exactly the previous output time
  long stalled = 0;
  std::vector<int> stall_surfaces;  // the surfaces crossed by the stalled events
  std::vector<char> ignored(model.surface_count(), 0);
  double escape_until = -1.0;
  int escapes = 0;
  Eigen::VectorXd z;
  std::vector<Eigen::VectorXd> derivatives;
  LegEnd end;
  int k = 0;
  if (summary.message.empty()) {
    if (times.front() == 0.0) {
      integrator->Record(&recorder, 0, times[0]);
      if (observer != nullptr) observer->Recorded(0, phases);
      k = 1;
    } else {
      from_output = false;
    }
  }

  while (k < samples && summary.message.empty()) {
    const double t_grid = times[k];
    Leg leg;
    leg.output_time = t_grid;
    leg.target = t_grid;
    if (next_breakpoint < breakpoints.size() &&
        breakpoints[next_breakpoint] <= t_grid * (1.0 + 4 * kEps)) {
      leg.breakpoint = breakpoints[next_breakpoint];
      leg.target = std::min(leg.breakpoint, t_grid);
      leg.at_breakpoint = true;
    }
    leg.at_output = leg.target >= t_grid * (1.0 - 4 * kEps);
    if (leg.at_output) leg.target = t_grid;
    const bool escaping = escape_until > t;
    const bool escape_ends = escaping && escape_until < leg.target;
    if (escape_ends) {
      leg.target = escape_until;
      leg.at_output = false;
      leg.at_breakpoint = false;
    }
    leg.from_output = from_output;
    leg.next_stop = next_breakpoint < breakpoints.size()
                        ? std::min(breakpoints[next_breakpoint], times.back())
                        : times.back();
    leg.ignored = escaping ? &ignored : nullptr;
    integrator->Advance(t, leg, &end);

    if (end.kind == LegEnd::Kind::kFailed) {
      summary.message = end.message;
      break;
    }
    if (end.kind == LegEnd::Kind::kEvent) {
      integrator->EventMotion(&z, &derivatives);
      const Phases next = model.Classify(z, derivatives, end.crossed, &phases);
      if (observer != nullptr) {
        observer->LegEnded(end.elapsed, phases, z, escaping);
        observer->Switched(phases, next, end.crossed);
      }
      if (end.elapsed <=
          std::max(kStallUlps * kEps * std::max(std::abs(t), h), kChatterFraction * h)) {
        for (const Model::KnownSide& side : end.crossed) stall_surfaces.push_back(side.surface);
        if (++stalled > kMaxStalledEvents) {
          if (escapes >= kMaxEscapes) {
            summary.message = "events do not advance time at t = " + std::to_string(t) +
                              " (chattering between " + model.DescribePhases(phases) + " and " +
                              model.DescribePhases(next) + ")";
            break;
          }
          // A degenerate switch (a link pushed from rest: contact, release and the damping cap
          // meet at one point, and the motion starts at a high order): step on for a short time
          // in the phases reached, blind to the surfaces that chattered, then watch them again.
          escape_until = end.t + h * kEscapeFraction[escapes];
          ++escapes;
          for (int index : stall_surfaces) ignored[index] = 1;
          stalled = 0;
        }
      } else {
        stalled = 0;
        stall_surfaces.clear();
      }
      t = end.t;
      summary.event_times_s.push_back(t);
      phases = next;
      integrator->Switch(phases, t);
      from_output = false;
      if (++summary.events > options.max_events) {
        summary.message = "more than max_events = " + std::to_string(options.max_events) +
                          " switching events by t = " + std::to_string(t);
        break;
      }
      continue;
    }

    t = end.t;
    if (observer != nullptr) {
      integrator->State(&z);
      observer->LegEnded(end.elapsed, phases, z, escaping);
    }
    if (escape_ends) {  // watch every surface again
      std::fill(ignored.begin(), ignored.end(), 0);
      escape_until = -1.0;
      stall_surfaces.clear();
    }
    if (leg.at_breakpoint) {
      integrator->ApplyBreakpoint(leg.breakpoint, t);
      ++next_breakpoint;
      if (observer != nullptr) {
        integrator->State(&z);
        observer->BreakpointApplied(leg.breakpoint, z);
      }
    }
    from_output = leg.at_output;
    if (leg.at_output) {
      integrator->Record(&recorder, k, t_grid);
      if (observer != nullptr) observer->Recorded(k, phases);
      ++k;
      if (!escaping) escapes = 0;
    }
  }
  integrator->Finish(&summary);
  summary.success = summary.message.empty();
  summary.wall_time_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  return result;
}

}  // namespace millkit::driveline
