// CVODES solver for the drive line (issue 2). See simulation.h for the contract.
// Between events the model is x' = A x + B w(t) with w linear in time between input breakpoints;
// the Jacobian is A exactly. Root functions are the watched switching surfaces of the current
// phases; at a root the integrator stops, the phases flip (the crossed surface's new side is the
// root's direction) and CVODE is reinitialised. Input breakpoints are stop times.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <exception>
#include <limits>

#include "driveline/output_recorder.h"
#include "millkit/driveline/simulation.h"
#include "numerics/sundials_handles.h"

namespace millkit::driveline {
namespace {

using numerics::CvodeMemory;
using numerics::SundialsContext;
using numerics::SundialsLinearSolver;
using numerics::SundialsMatrix;
using numerics::SundialsVector;

constexpr double kEps = std::numeric_limits<double>::epsilon();
constexpr int kMaxStalledEvents = 64;
// Root functions are the signed surfaces plus this fraction of their typical magnitude. CVODE
// deactivates a root function that is zero at the start of an integration and never reports a
// crossing of it afterwards: a link resting exactly on a flank (gap_position ±1) and pushed
// into contact would be missed. With the margin the function starts positive and the crossing
// is reported a roundoff-sized distance past the surface (the exact solver's kCrossingTolerance).
constexpr double kCrossingMargin = 1e-13;

// Everything the C callbacks read. Callbacks are noexcept and report failure by return code.
struct Problem {
  const Model* model = nullptr;
  int nx = 0;
  Eigen::MatrixXd a, b;       // current phases
  Eigen::VectorXd w0, slope;  // forcing at t_segment and its slope
  double t_segment = 0.0;
  Eigen::MatrixXd rows;    // watched surfaces over [x; w], signed (>= 0 on the watched side)
  Eigen::VectorXd margin;  // per watched surface: kCrossingMargin × its typical magnitude
  std::vector<Model::WatchedSurface> watched;

  Eigen::VectorXd Forcing(double t) const { return w0 + slope * (t - t_segment); }
};

int Rhs(sunrealtype t, N_Vector y, N_Vector ydot, void* user_data) noexcept {
  try {
    const auto& p = *static_cast<const Problem*>(user_data);
    Eigen::Map<const Eigen::VectorXd> x(N_VGetArrayPointer(y), p.nx);
    Eigen::Map<Eigen::VectorXd> xdot(N_VGetArrayPointer(ydot), p.nx);
    xdot.noalias() = p.a * x + p.b * p.Forcing(t);
    return 0;
  } catch (...) {
    return -1;
  }
}

int Jacobian(sunrealtype, N_Vector, N_Vector, SUNMatrix jac, void* user_data, N_Vector, N_Vector,
             N_Vector) noexcept {
  const auto& p = *static_cast<const Problem*>(user_data);
  for (int j = 0; j < p.nx; ++j) {
    sunrealtype* column = SUNDenseMatrix_Column(jac, j);
    for (int i = 0; i < p.nx; ++i) column[i] = p.a(i, j);
  }
  return 0;
}

int Roots(sunrealtype t, N_Vector y, sunrealtype* g, void* user_data) noexcept {
  try {
    const auto& p = *static_cast<const Problem*>(user_data);
    Eigen::Map<const Eigen::VectorXd> x(N_VGetArrayPointer(y), p.nx);
    const Eigen::VectorXd w = p.Forcing(t);
    for (int i = 0; i < static_cast<int>(p.watched.size()); ++i) {
      g[i] = p.rows.row(i).head(p.nx).dot(x) + p.rows.row(i).tail(w.size()).dot(w) + p.margin[i];
    }
    return 0;
  } catch (...) {
    return -1;
  }
}

std::string FlagName(int flag) {
  char* name = CVodeGetReturnFlagName(flag);
  std::string text = name != nullptr ? name : std::to_string(flag);
  free(name);  // CVodeGetReturnFlagName allocates with malloc
  return text;
}

}  // namespace

SimulationResult SimulateCvode(const Model& model, const SimulationOptions& options) {
  options.Validate(model.scene());
  const auto started = std::chrono::steady_clock::now();
  const Scene& scene = model.reduced_scene();  // outputs convert back in the recorder
  SimulationResult result;
  SimulationSummary& summary = result.summary;
  summary.solver = "cvode";
  summary.reduction = model.reduction().report;
  summary.error_kind = "requested tolerance";
  summary.error_estimate = options.rtol;
  OutputRecorder recorder(model, options, &result);
  const OutputGrid& times = recorder.times();
  const int samples = recorder.size();
  // Time scale for "events that do not advance time".
  const double h = 1.0 / scene.sample_rate_Hz;
  const int nx = model.state_size(), nw = model.forcing_size();

  Eigen::VectorXd z = model.InitialState();
  if (options.initial_state) z.head(nx) = options.initial_state->head(nx);
  Phases phases = model.InitialPhases(z);

  Problem problem;
  problem.model = &model;
  problem.nx = nx;
  problem.w0 = z.segment(nx, nw);
  problem.slope = z.tail(nw);
  const Eigen::VectorXd state_scale = model.StateScale();
  auto configure = [&](const Phases& p) {
    model.LinearPieces(p, &problem.a, &problem.b);
    problem.watched = model.Watched(p);
    problem.rows.resize(static_cast<int>(problem.watched.size()), nx + nw);
    problem.margin.resize(static_cast<int>(problem.watched.size()));
    for (size_t i = 0; i < problem.watched.size(); ++i) {
      const int r = static_cast<int>(i);
      problem.rows.row(r) =
          problem.watched[i].side * model.surfaces().row(problem.watched[i].index).head(nx + nw);
      problem.margin[r] =
          kCrossingMargin *
          (problem.rows.row(r).head(nx).cwiseAbs().dot(state_scale) +
           problem.rows.row(r).tail(nw).cwiseAbs().dot(problem.w0.cwiseAbs().cwiseMax(1.0)));
    }
  };
  auto record = [&](int sample, double t, const Eigen::VectorXd& x) {
    Eigen::VectorXd state(model.augmented_size());
    state << x, problem.Forcing(t), problem.slope;
    recorder.Record(sample, phases, state);
  };
  int k = 0;
  if (times.front() == 0.0) {
    record(0, 0.0, z.head(nx));
    k = 1;
  }
  configure(phases);

  SundialsContext context;
  SundialsVector y(N_VNew_Serial(nx, context.get()));
  SundialsVector atol(N_VNew_Serial(nx, context.get()));
  Eigen::Map<Eigen::VectorXd> y_data(N_VGetArrayPointer(y.get()), nx);
  y_data = z.head(nx);
  Eigen::Map<Eigen::VectorXd>(N_VGetArrayPointer(atol.get()), nx) =
      options.atol.value_or(options.rtol) * model.StateScale();
  SundialsMatrix jac(SUNDenseMatrix(nx, nx, context.get()));
  SundialsLinearSolver solver(SUNLinSol_Dense(y.get(), jac.get(), context.get()));
  CvodeMemory memory(CVodeCreate(CV_BDF, context.get()));
  void* mem = memory.get();

  const std::vector<double> breakpoints = scene.InputBreakpoints();
  size_t next_breakpoint = 0;
  // The run ends at the last output time: no stop at a breakpoint after it.
  const double t_final = times.back();
  auto stop_time = [&] {
    return next_breakpoint < breakpoints.size() ? std::min(breakpoints[next_breakpoint], t_final)
                                                : t_final;
  };
  auto check = [&](int flag, const char* call) {
    if (flag < 0) throw std::runtime_error(std::string(call) + " failed: " + FlagName(flag));
  };
  long steps = 0, rhs = 0, jacs = 0;
  auto harvest = [&] {
    long value = 0;
    CVodeGetNumSteps(mem, &value);
    steps += value;
    CVodeGetNumRhsEvals(mem, &value);
    rhs += value;
    CVodeGetNumJacEvals(mem, &value);
    jacs += value;
  };
  auto set_roots = [&] {
    check(CVodeRootInit(mem, static_cast<int>(problem.watched.size()),
                        problem.watched.empty() ? nullptr : Roots),
          "CVodeRootInit");
  };

  try {
    check(CVodeInit(mem, Rhs, 0.0, y.get()), "CVodeInit");
    check(CVodeSVtolerances(mem, options.rtol, atol.get()), "CVodeSVtolerances");
    check(CVodeSetUserData(mem, &problem), "CVodeSetUserData");
    check(CVodeSetLinearSolver(mem, solver.get(), jac.get()), "CVodeSetLinearSolver");
    check(CVodeSetJacFn(mem, Jacobian), "CVodeSetJacFn");
    check(CVodeSetMaxNumSteps(mem, options.max_steps), "CVodeSetMaxNumSteps");
    check(CVodeSetNoInactiveRootWarn(mem), "CVodeSetNoInactiveRootWarn");
    check(CVodeSetStopTime(mem, stop_time()), "CVodeSetStopTime");
    set_roots();
    auto reinit = [&](double t) {
      harvest();
      check(CVodeReInit(mem, t, y.get()), "CVodeReInit");
      set_roots();
      check(CVodeSetStopTime(mem, stop_time()), "CVodeSetStopTime");
    };

    double last_event_t = -1.0;
    int stalled = 0;
    std::vector<int> roots_found;
    double t = 0.0;
    while (k < samples && summary.message.empty()) {
      const double tout = times[k];
      if (tout - t <= 4 * kEps * std::max(1.0, tout)) {
        // An event or a breakpoint landed on this sample time: the state is already there.
        record(k, tout, y_data);
        ++k;
        continue;
      }
      const int flag = CVode(mem, tout, y.get(), &t, CV_NORMAL);
      if (flag == CV_ROOT_RETURN) {
        roots_found.assign(problem.watched.size(), 0);
        check(CVodeGetRootInfo(mem, roots_found.data()), "CVodeGetRootInfo");
        std::vector<Model::KnownSide> known;
        for (size_t i = 0; i < roots_found.size(); ++i) {
          // The signed function falls through zero: the surface's new side is −side.
          if (roots_found[i] != 0) {
            known.push_back({problem.watched[i].index, roots_found[i] * problem.watched[i].side});
          }
        }
        Eigen::VectorXd state(model.augmented_size());
        state << y_data, problem.Forcing(t), problem.slope;
        const Eigen::MatrixXd m = model.SystemMatrix(phases);
        const Eigen::VectorXd zdot = m * state;
        phases = model.Classify(state, zdot, m * zdot, known);
        configure(phases);
        if (t - last_event_t <= 64 * kEps * std::max(std::abs(t), h)) {
          if (++stalled > kMaxStalledEvents) {
            summary.message = "events do not advance time at t = " + std::to_string(t);
          }
        } else {
          stalled = 0;
        }
        last_event_t = t;
        summary.event_times_s.push_back(t);
        if (++summary.events > options.max_events) {
          summary.message = "more than max_events switching events by t = " + std::to_string(t);
        }
        reinit(t);
        continue;
      }
      if (flag == CV_TSTOP_RETURN) {
        if (next_breakpoint < breakpoints.size() && t >= breakpoints[next_breakpoint]) {
          ++next_breakpoint;
          for (int s = 0; s < nw - 1; ++s) {
            problem.w0[1 + s] = scene.torques[s].ValueAt(t);
            problem.slope[1 + s] = scene.torques[s].SlopeAt(t);
          }
          problem.t_segment = t;
          reinit(t);
        }
        if (std::abs(t - tout) <= 4 * kEps * std::max(1.0, tout)) {
          record(k, tout, y_data);
          ++k;
        }
        continue;
      }
      if (flag < 0) {
        summary.message = "CVode failed at t = " + std::to_string(t) + ": " + FlagName(flag);
        break;
      }
      if (!y_data.allFinite()) {
        summary.message = "state became non-finite at t = " + std::to_string(t);
        break;
      }
      record(k, tout, y_data);
      ++k;
    }
    harvest();
  } catch (const std::exception& e) {
    if (recorder.callback_error()) throw;  // the caller's sink or progress, not a solver failure
    summary.message = e.what();
  }
  summary.steps = steps;
  summary.rhs_evaluations = rhs;
  summary.jacobian_evaluations = jacs;
  summary.success = summary.message.empty();
  summary.wall_time_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  return result;
}

}  // namespace millkit::driveline
