// Event-exact piecewise-linear solver (issue 2). See simulation.h for the contract.
//
// Within one phase set the augmented ODE z' = M z is autonomous and linear, so
// z(t + τ) = exp(M τ) z(t) exactly (Padé scaling-and-squaring, Eigen's MatrixFunctions).
// A step from one output sample to the next uses the propagator exp(M h) cached per phase set;
// a step of any other length (to an event, a breakpoint) uses the action exp(M τ) z by Taylor
// series (numerics/expm_action.h), which is exact to roundoff as well.
// A watched surface g = r·z that changes side within a step is a switching event; g(τ) is
// known exactly along the step, so its root is found by Newton iteration on the exact solution,
// started from the cubic Hermite interpolant of g and safeguarded by bisection. A surface that
// dips across and back within a step is caught from its end derivatives (a minimum inside).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <unordered_map>

#include <unsupported/Eigen/MatrixFunctions>

#include "driveline/output_recorder.h"
#include "driveline/simulation.h"
#include "numerics/expm_action.h"

namespace millkit::driveline {
namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();
// A surface that ends a step past zero by less than this fraction of its terms has not crossed.
constexpr double kCrossingTolerance = 1e-13;
// Events closer in time than this many ulps of t count as "not advancing".
constexpr double kStallUlps = 64.0;
constexpr int kMaxStalledEvents = 64;
constexpr int kMaxRootIterations = 100;

// Typical magnitude of each component of z: states from the model, forcing from the sources.
Eigen::VectorXd AugmentedScale(const Model& model) {
  const int nx = model.state_size(), nw = model.forcing_size();
  Eigen::VectorXd scale = Eigen::VectorXd::Ones(model.augmented_size());
  scale.head(nx) = model.StateScale();
  const auto& torques = model.scene().torques;
  for (int s = 0; s < nw - 1; ++s) {
    double value = 0.0, slope = 0.0;
    const auto& source = torques[s];
    for (size_t i = 0; i < source.times_s.size(); ++i) {
      value = std::max(value, std::abs(source.values_Nm[i]));
      if (i > 0 && source.times_s[i] > source.times_s[i - 1]) {
        slope = std::max(slope, std::abs(source.values_Nm[i] - source.values_Nm[i - 1]) /
                                    (source.times_s[i] - source.times_s[i - 1]));
      }
    }
    scale[nx + 1 + s] = std::max(value, 1.0);
    scale[nx + nw + 1 + s] = std::max(slope, 1.0);
  }
  return scale;
}

// Everything here is in scaled coordinates y = D⁻¹ z, D = diag(typical magnitudes): the
// similarity D⁻¹ M D has a norm near the fastest mode's frequency, where the raw M mixes units
// (N·m/rad over kg·m² next to 1) and makes exp() lose digits in needless squarings.
struct PhaseData {
  Eigen::MatrixXd system;  // M itself, for the outputs of rigid links
  Eigen::MatrixXd m;     // D⁻¹ M D
  Eigen::MatrixXd step;  // exp(M h), built on first use
  bool has_step = false;
  double defect = 0.0;  // roundoff of one step, relative to the state scale
  double norm1 = 0.0;   // ‖m‖₁
  std::vector<Model::WatchedSurface> watched;
  Eigen::MatrixXd rows;  // watched surface rows times D
  Eigen::MatrixXd rows_m;  // rows · m: time derivatives of the watched surfaces
};

// Values and time derivatives of the watched surfaces at one state.
struct SurfaceValues {
  Eigen::VectorXd g, dg;
};

class ExactIntegrator {
 public:
  ExactIntegrator(const Model& model, const SimulationOptions& options)
      : model_(model), options_(options) {}

  SimulationResult Run();

 private:
  PhaseData& Data(const Phases& phases);
  // z(τ) from z(0) within one phase set, for arbitrary τ (events, breakpoints).
  Eigen::VectorXd Propagate(const PhaseData& data, const Eigen::VectorXd& z, double tau) {
    Eigen::VectorXd y = z;
    numerics::ExpmAction(data.m, data.norm1, tau, &y, &term_, &next_);
    return y;
  }
  // Finds the earliest crossing of a watched surface over (0, tau] of the step from z0 (end state
  // z1). Returns false when none. On success sets *tau_event, *z_event and *crossed (index into
  // data.watched).
  bool FindEvent(const PhaseData& data, double t, const Eigen::VectorXd& z0,
                 const Eigen::VectorXd& z1, const SurfaceValues& start, const SurfaceValues& end,
                 double tau, double* tau_event, Eigen::VectorXd* z_event, int* crossed);
  // Root of side·g over [lo, hi] (side·g(lo) >= 0 > side·g(hi)) for watched surface w.
  double Refine(const PhaseData& data, int w, double t, const Eigen::VectorXd& z0, double lo,
                double hi, double guess, Eigen::VectorXd* z_root);
  void Record(OutputRecorder* recorder, int sample, const Phases& phases, const PhaseData& data,
              const Eigen::VectorXd& y);
  // Builds exp(M h) for a phase set, with its roundoff defect ‖exp(Mh) − exp(Mh/3)³‖ in the
  // scaled norm (the error estimate accumulates it per step).
  void BuildStep(PhaseData* data);

  const Model& model_;
  const SimulationOptions& options_;
  std::unordered_map<Phases, PhaseData> cache_;
  double h_ = 0.0;
  Eigen::VectorXd scale_;  // typical magnitude of each component of z
  SimulationResult result_;
  Eigen::VectorXd term_, next_;  // work space of Propagate
};

PhaseData& ExactIntegrator::Data(const Phases& phases) {
  auto it = cache_.find(phases);
  if (it != cache_.end()) return it->second;
  PhaseData data;
  data.system = model_.SystemMatrix(phases);
  data.m = scale_.cwiseInverse().asDiagonal() * data.system * scale_.asDiagonal();
  data.norm1 = data.m.cwiseAbs().colwise().sum().maxCoeff();
  data.watched = model_.Watched(phases);
  data.rows.resize(static_cast<int>(data.watched.size()), model_.augmented_size());
  for (size_t i = 0; i < data.watched.size(); ++i) {
    data.rows.row(static_cast<int>(i)) =
        model_.surfaces().row(data.watched[i].index) * scale_.asDiagonal();
  }
  data.rows_m = data.rows * data.m;
  return cache_.emplace(phases, std::move(data)).first->second;
}

// Cubic Hermite interpolant of g on [0, tau] from values and derivatives at the ends, at s.
double Hermite(double g0, double d0, double g1, double d1, double tau, double s) {
  const double u = s / tau;
  const double h00 = (1 + 2 * u) * (1 - u) * (1 - u), h10 = u * (1 - u) * (1 - u);
  const double h01 = u * u * (3 - 2 * u), h11 = u * u * (u - 1);
  return h00 * g0 + h10 * tau * d0 + h01 * g1 + h11 * tau * d1;
}

// Where the Hermite cubic, falling at 0 (d0 < 0) and rising at tau (d1 > 0), has its minimum:
// the root in (0, 1) of its quadratic derivative in u = s / tau.
double HermiteMinimum(double g0, double d0, double g1, double d1, double tau) {
  const double q = 6.0 * (g0 - g1) / tau;
  const double a = q + 3.0 * d0 + 3.0 * d1, b = -q - 4.0 * d0 - 2.0 * d1, c = d0;
  double u = 0.5;
  if (std::abs(a) < 1e-300) {
    u = b != 0.0 ? -c / b : 0.5;
  } else {
    const double disc = std::sqrt(std::max(0.0, b * b - 4.0 * a * c));
    // The root where the derivative changes from negative to positive.
    const double r1 = (-b - disc) / (2.0 * a), r2 = (-b + disc) / (2.0 * a);
    u = (a > 0.0) ? std::max(r1, r2) : std::min(r1, r2);
  }
  return tau * std::clamp(u, 0.0, 1.0);
}

// Root of the Hermite cubic on [lo, hi] with a sign change (bisection on the cheap cubic).
double HermiteRoot(double g0, double d0, double g1, double d1, double tau, double lo, double hi) {
  double f_lo = Hermite(g0, d0, g1, d1, tau, lo);
  for (int i = 0; i < 60; ++i) {
    const double mid = 0.5 * (lo + hi);
    const double f_mid = Hermite(g0, d0, g1, d1, tau, mid);
    if ((f_mid > 0) == (f_lo > 0)) {
      lo = mid;
      f_lo = f_mid;
    } else {
      hi = mid;
    }
  }
  return 0.5 * (lo + hi);
}

double ExactIntegrator::Refine(const PhaseData& data, int w, double t, const Eigen::VectorXd& z0,
                               double lo, double hi, double guess, Eigen::VectorXd* z_root) {
  const auto row = data.rows.row(w);
  const double side = data.watched[w].side;
  const double resolution = kStallUlps * kEps * std::max(std::abs(t) + hi, h_);
  double tau = std::clamp(guess, lo, hi);
  Eigen::VectorXd z_hi;
  for (int iteration = 0; iteration < kMaxRootIterations; ++iteration) {
    const Eigen::VectorXd z = Propagate(data, z0, tau);
    const double g = side * row.dot(z);
    if (g >= 0.0) {
      lo = tau;
    } else {
      hi = tau;
      z_hi = z;
    }
    if (hi - lo <= resolution) break;
    const double dg = side * row.dot(data.m * z);
    double next = dg != 0.0 ? tau - g / dg : 0.5 * (lo + hi);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    // Newton at the root to roundoff: nudge across it so that the bracket closes.
    if (std::abs(next - tau) < 0.5 * resolution) {
      next = std::clamp(tau + (g >= 0.0 ? 0.5 : -0.5) * resolution, lo, hi);
    }
    tau = next;
  }
  *z_root = z_hi.size() > 0 && tau == hi ? z_hi : Propagate(data, z0, hi);
  return hi;
}

bool ExactIntegrator::FindEvent(const PhaseData& data, double t, const Eigen::VectorXd& z0,
                                const Eigen::VectorXd& z1, const SurfaceValues& start,
                                const SurfaceValues& end, double tau, double* tau_event,
                                Eigen::VectorXd* z_event, int* crossed) {
  const int count = static_cast<int>(data.watched.size());
  if (count == 0) return false;
  const Eigen::VectorXd& g0 = start.g;
  const Eigen::VectorXd& g1 = end.g;
  const Eigen::VectorXd& d0 = start.dg;
  const Eigen::VectorXd& d1 = end.dg;
  double best = std::numeric_limits<double>::infinity();
  int best_w = -1;
  double best_hi = tau;
  for (int w = 0; w < count; ++w) {
    const double side = data.watched[w].side;
    const double a0 = side * g0[w], a1 = side * g1[w], b0 = side * d0[w], b1 = side * d1[w];
    double estimate = -1.0, hi = tau;
    if (a1 < 0.0) {
      const double scale = (data.rows.row(w).cwiseAbs() * z1.cwiseAbs())(0);
      if (a1 < -kCrossingTolerance * scale) {
        estimate = HermiteRoot(std::max(a0, 0.0), b0, a1, b1, tau, 0.0, tau);
      }
    } else if (b0 < 0.0 && b1 > 0.0) {
      // Moving towards the surface at the start and away at the end: a minimum inside. When the
      // interpolant comes close to the surface there, look at the exact solution.
      const double s_min = HermiteMinimum(a0, b0, a1, b1, tau);
      if (Hermite(a0, b0, a1, b1, tau, s_min) < 0.25 * std::min(a0, a1)) {
        const Eigen::VectorXd z_min = Propagate(data, z0, s_min);
        const double scale_min = (data.rows.row(w).cwiseAbs() * z_min.cwiseAbs())(0);
        const double a_min = side * data.rows.row(w).dot(z_min);
        if (a_min < -kCrossingTolerance * scale_min) {
          hi = s_min;
          estimate = HermiteRoot(std::max(a0, 0.0), b0, a_min, 0.0, s_min, 0.0, s_min);
        }
      }
    }
    if (estimate >= 0.0 && estimate < best) {
      best = estimate;
      best_w = w;
      best_hi = hi;
    }
  }
  if (best_w < 0) return false;
  // Refine the earliest candidate; if another surface turns out to have crossed before it,
  // refine that one on the shorter interval.
  double hi = best_hi;
  int w = best_w;
  double guess = best;
  Eigen::VectorXd z_root;
  for (int round = 0; round <= count; ++round) {
    const double root = Refine(data, w, t, z0, 0.0, hi, guess, &z_root);
    int earlier = -1;
    for (int v = 0; v < count; ++v) {
      if (v == w) continue;
      const double scale = (data.rows.row(v).cwiseAbs() * z_root.cwiseAbs())(0);
      if (data.watched[v].side * data.rows.row(v).dot(z_root) < -kCrossingTolerance * scale) {
        // Crossed by root: only earlier if it was not already past at the step start.
        if (data.watched[v].side * g0[v] >= -kCrossingTolerance * scale) earlier = v;
      }
    }
    hi = root;
    if (earlier < 0) {
      *tau_event = root;
      *z_event = z_root;
      *crossed = w;
      return true;
    }
    w = earlier;
    guess = 0.5 * root;
  }
  *tau_event = hi;
  *z_event = z_root;
  *crossed = w;
  return true;
}

void ExactIntegrator::Record(OutputRecorder* recorder, int sample, const Phases& phases,
                             const PhaseData& data, const Eigen::VectorXd& y) {
  recorder->Record(sample, phases, scale_.cwiseProduct(y), &data.system);
}

void ExactIntegrator::BuildStep(PhaseData* data) {
  data->step = (data->m * h_).exp();
  data->has_step = true;
  ++result_.summary.phase_sets;
  if (!options_.estimate_error) return;
  // exp(2Mh) would repeat the squaring of exp(Mh) bit for bit; a third of the step takes another
  // rounding path through the Padé approximant.
  const Eigen::MatrixXd third = (data->m * (h_ / 3.0)).exp();
  data->defect = (data->step - third * third * third).cwiseAbs().rowwise().sum().maxCoeff();
}

// The step whose propagator is cached per phase set: the scene's sample interval, or for given
// output times the median gap (an oscillogram's sampling interval).
double CachedStep(const Scene& scene, const SimulationOptions& options,
                  const std::vector<double>& times) {
  if (!options.output_times || times.size() < 2) return 1.0 / scene.sample_rate_Hz;
  std::vector<double> gaps(times.size() - 1);
  for (size_t k = 1; k < times.size(); ++k) gaps[k - 1] = times[k] - times[k - 1];
  std::nth_element(gaps.begin(), gaps.begin() + gaps.size() / 2, gaps.end());
  return gaps[gaps.size() / 2];
}

SimulationResult ExactIntegrator::Run() {
  const auto started = std::chrono::steady_clock::now();
  const Scene& scene = model_.scene();
  SimulationSummary& summary = result_.summary;
  summary.solver = "exact";
  summary.reduction = model_.reduction().report;
  OutputRecorder recorder(model_, options_, OutputTimes(scene, options_), &result_);
  const std::vector<double>& times = recorder.times();
  const int samples = recorder.size();
  h_ = CachedStep(scene, options_, times);
  scale_ = AugmentedScale(model_);

  Eigen::VectorXd z0 = model_.InitialState();
  if (options_.initial_state) {
    z0.head(model_.state_size()) = options_.initial_state->head(model_.state_size());
  }
  Phases phases = model_.InitialPhases(z0);
  Eigen::VectorXd z = scale_.cwiseInverse().cwiseProduct(z0);  // scaled state y
  const std::vector<double> breakpoints = scene.InputBreakpoints();
  size_t next_breakpoint = 0;
  double t = 0.0;
  bool on_grid = true;  // t is exactly the previous output time
  long stalled = 0;
  Eigen::VectorXd z1(z.size()), z_event(z.size());
  SurfaceValues start, end;  // watched surfaces at the step's start and end
  bool start_valid = false;
  int k = 0;
  if (times.front() == 0.0) {
    Record(&recorder, 0, phases, Data(phases), z);
    k = 1;
  } else {
    on_grid = false;
  }

  while (k < samples) {
    PhaseData& data = Data(phases);
    const double t_grid = times[k];
    double target = t_grid;
    bool at_breakpoint = false;
    if (next_breakpoint < breakpoints.size() &&
        breakpoints[next_breakpoint] <= t_grid * (1.0 + 4 * kEps)) {
      target = std::min(breakpoints[next_breakpoint], t_grid);
      at_breakpoint = true;
    }
    const bool at_grid = target >= t_grid * (1.0 - 4 * kEps);
    if (at_grid) target = t_grid;
    const double tau = target - t;
    // The cached exp(M h) serves a step between output times whose gap is h to roundoff of the
    // times themselves (the state lands a few ulps of t off: as exact as t can be stated).
    const bool cached_step =
        on_grid && at_grid && std::abs(tau - h_) <= 8 * kEps * std::max(std::abs(t_grid), h_);
    if (cached_step) {
      if (!data.has_step) BuildStep(&data);
      z1.noalias() = data.step * z;
      summary.error_estimate += data.defect;
    } else {
      z1 = Propagate(data, z, tau);
    }
    ++summary.steps;
    if (!z1.allFinite()) {
      summary.message = "state became non-finite at t = " + std::to_string(t);
      break;
    }
    if (!start_valid) {
      start.g.noalias() = data.rows * z;
      start.dg.noalias() = data.rows_m * z;
    }
    end.g.noalias() = data.rows * z1;
    end.dg.noalias() = data.rows_m * z1;
    double tau_event = 0.0;
    int crossed = -1;
    if (FindEvent(data, t, z, z1, start, end, tau, &tau_event, &z_event, &crossed)) {
      start_valid = false;
      const Eigen::VectorXd ydot = data.m * z_event;
      const Model::WatchedSurface surface = data.watched[crossed];
      const Phases next = model_.Classify(
          scale_.cwiseProduct(z_event), scale_.cwiseProduct(ydot),
          scale_.cwiseProduct(data.m * ydot), {{surface.index, -surface.side}});
      if (tau_event <= kStallUlps * kEps * std::max(std::abs(t), h_)) {
        if (++stalled > kMaxStalledEvents) {
          summary.message = "events do not advance time at t = " + std::to_string(t) +
                            " (chattering between " + model_.DescribePhases(phases) + " and " +
                            model_.DescribePhases(next) + ")";
          break;
        }
      } else {
        stalled = 0;
      }
      t += tau_event;
      summary.event_times_s.push_back(t);
      z = z_event;
      phases = next;
      on_grid = false;
      if (++summary.events > options_.max_events) {
        summary.message = "more than max_events = " + std::to_string(options_.max_events) +
                          " switching events by t = " + std::to_string(t);
        break;
      }
      continue;
    }
    z.swap(z1);
    std::swap(start, end);
    start_valid = true;
    t = target;
    if (at_breakpoint) {
      // Inputs from their right limit at the breakpoint itself: a breakpoint snapped onto a
      // sample time a few ulps away must not be read as still inside the ramp before it.
      Eigen::VectorXd unscaled = scale_.cwiseProduct(z);
      model_.SetForcing(breakpoints[next_breakpoint], &unscaled);
      z = scale_.cwiseInverse().cwiseProduct(unscaled);
      start_valid = false;
      ++next_breakpoint;
    }
    if (at_grid) {
      on_grid = true;
      Record(&recorder, k, phases, data, z);
      ++k;
    } else {
      on_grid = false;
    }
  }
  summary.success = summary.message.empty();
  summary.wall_time_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  return std::move(result_);
}

}  // namespace

SimulationResult SimulateExact(const Model& model, const SimulationOptions& options) {
  options.Validate(model.scene());
  ExactIntegrator integrator(model, options);
  return integrator.Run();
}

}  // namespace millkit::driveline
