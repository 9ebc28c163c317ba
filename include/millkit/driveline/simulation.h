// Simulating a drive-line model: one interface, two solvers (SPEC.md §2.7, issue 2).
//  - kExact: event-exact piecewise-linear solver. Within one set of phases the solution is exact to
//    roundoff: z(t + τ) = z + Φ(τ) z', z'(t + τ) = exp(M τ) z', Φ = ∫₀^τ exp(M s) ds, which also
//    keeps a state at rest exactly at rest. Switching events are found on that exact solution
//    (bounds first, then its Taylor polynomial; Newton with bisection safeguard to a few ulps of
//    time). The propagators over one output step are cached per phase set once it has lasted a
//    few steps; a stiff phase set (fast drive loop, heavy damping) is stepped on a ladder of
//    exact propagators over h / 2^j at a cost that grows with log(‖M‖ h) (exact_solver.cpp).
//  - kCvode: SUNDIALS CVODES (BDF, dense Newton, exact Jacobian), root functions on the watched
//    switching surfaces, stop at each event, flip the phases and reinitialise; input breakpoints
//    are stop times.
// Both return the same sampled output and a Summary. A run that cannot finish (non-finite state,
// too many events, events that do not advance time, CVODE failure) is reported in the Summary
// (success = false, message), never by an exception.
#pragma once

#include <Eigen/Dense>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "millkit/driveline/model.h"

namespace millkit::driveline {

enum class SolverKind { kExact, kCvode };

// The solvers, from one registry (in SolverKind order): each is a per-phase-set integrator run by
// the same hybrid event loop (output times, breakpoints, event policy, summary).
struct SolverInfo {
  SolverKind kind;
  const char* name;         // as `--solver` and configs spell it
  const char* description;  // one line
};
const std::vector<SolverInfo>& Solvers();
const SolverInfo& SolverOf(SolverKind kind);
// The solver named `name`, or nullptr.
const SolverInfo* FindSolver(std::string_view name);
// "exact, cvode": the names, for messages and help.
std::string SolverNames();

// One output sample as SimulationOptions::sample_sink receives it: the values the sample matrices
// of SimulationResult would hold, bit for bit, in each object's own units. The rows are valid only
// during the call.
struct OutputSample {
  int index = 0;  // k, among the run's output times
  double time_s = 0.0;
  const double* link_torque_Nm = nullptr;        // one per scene link
  const double* mass_speed_rad_per_s = nullptr;  // one per scene mass
  const double* link_twist_rad = nullptr;        // one per scene link
};

struct SimulationOptions {
  SolverKind solver = SolverKind::kExact;
  // CVODE only: relative tolerance, and absolute tolerance as a fraction of each state's typical
  // magnitude (Model::StateScale); atol = rtol when not given.
  double rtol = 1e-8;
  std::optional<double> atol;
  long max_steps = 50'000'000;  // CVODE internal steps
  long max_events = 1'000'000;
  // Exact solver: estimate the roundoff of each cached step propagator (‖e^{Mh} − (e^{Mh/3})³‖,
  // one extra exponential per phase set) and accumulate it over the steps taken.
  bool estimate_error = true;
  // Replaces Model::InitialState() (augmented state z; forcing part is set from the scene).
  std::optional<Eigen::VectorXd> initial_state;
  // Output times (s) replacing the scene's sample grid, e.g. the time column of an oscillogram
  // recorded at 1–10 kHz: non-empty, finite, strictly increasing, first >= 0, last <=
  // scene.duration_s. The run starts at t = 0 and ends at the last output time (no event after
  // it is simulated); result.time_s is these times.
  std::optional<std::vector<double>> output_times;
  // false: the sample matrices and time_s of the result stay empty and only the peak fields are
  // filled (the fast path for sweeps and optimisation that need only Kd).
  bool keep_samples = true;
  // Called with every output sample, in time order, once it is final. With keep_samples = false
  // nothing is held: the way to stream a long run to a file in bounded memory. An exception it
  // throws ends the run and propagates out of Simulate* (the Summary is lost).
  std::function<void(const OutputSample&)> sample_sink;
  // Called after every output sample with the fraction of the run's output samples done, in
  // (0, 1] (SimulateCvodeChecked: its two runs share the range); for a progress line. Same rule
  // for exceptions as sample_sink.
  std::function<void(double fraction)> progress;

  // Throws InputError naming the broken rule (e.g. rtol outside [1e-14, 1e-2]). Without a scene
  // the rule last output time <= duration is not checked; Simulate* check it.
  void Validate() const;
  void Validate(const Scene& scene) const;
};

struct SimulationSummary {
  std::string solver;
  bool success = false;
  std::string message;  // why it failed, empty on success
  long events = 0;      // phase switches
  long steps = 0;       // exact: propagations; CVODE: internal steps
  long rhs_evaluations = 0;
  long jacobian_evaluations = 0;
  long phase_sets = 0;  // distinct phase sets visited (exact: propagators built)
  // Exact: steps whose Taylor series was searched for a crossing because the bounds did not clear
  // every watched surface (the costly ones); CVODE: 0.
  long searched_steps = 0;
  double wall_time_s = 0.0;
  // What error_estimate is (BriefReport prints it with this name). Exact: "error estimate", the
  // step propagators' roundoff defects summed over the steps taken (a linear-growth bound),
  // relative to the states' typical magnitudes. CVODE: "requested tolerance" (rtol; CVODE does not
  // bound its global error), or from SimulateCvodeChecked "error vs rtol/10", the largest change
  // of a link torque when the run is repeated at a tenth of the tolerance, relative to the peak.
  std::string error_kind = "error estimate";
  double error_estimate = 0.0;
  std::vector<std::string> reduction;  // what the band-limited reduction merged
  std::vector<double> event_times_s;   // time of every phase switch, in order

  std::string BriefReport() const;
};

// Samples in rows, one row per output time (row-major, so a sample is contiguous).
using SampleMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

struct SimulationResult {
  // Empty when options.keep_samples is false.
  std::vector<double> time_s;
  SampleMatrix link_torque_Nm;        // samples × scene links
  SampleMatrix mass_speed_rad_per_s;  // samples × scene masses
  SampleMatrix link_twist_rad;        // samples × scene links
  // Always filled, one per scene link: max over the output samples of |link torque| (N·m) and the
  // first output time where it is reached (bit-identical with and without keep_samples).
  std::vector<double> peak_abs_torque_Nm;
  std::vector<double> peak_time_s;
  SimulationSummary summary;
};

// The times a run samples: options.output_times when given, else the scene grid k / sample_rate,
// k = 0 … SampleCount() − 1.
std::vector<double> OutputTimes(const Scene& scene, const SimulationOptions& options);

// The same times without holding the scene grid (a 1e4 s scene at 5 kHz has 5e7 of them): given
// output times are referenced, so `options` must outlive the grid; grid time k is computed as
// OutputTimes computes it, bit for bit.
class OutputGrid {
 public:
  OutputGrid(const Scene& scene, const SimulationOptions& options)
      : given_(options.output_times ? &*options.output_times : nullptr),
        h_(1.0 / scene.sample_rate_Hz),
        size_(given_ ? static_cast<int>(given_->size()) : scene.SampleCount()) {}
  int size() const { return size_; }
  double operator[](int k) const { return given_ ? (*given_)[k] : k * h_; }
  double front() const { return (*this)[0]; }
  double back() const { return (*this)[size_ - 1]; }

 private:
  const std::vector<double>* given_;
  double h_;
  int size_;
};

// Each validates the options against the model's scene first (throws InputError).
SimulationResult Simulate(const Model& model, const SimulationOptions& options);
SimulationResult SimulateExact(const Model& model, const SimulationOptions& options);
SimulationResult SimulateCvode(const Model& model, const SimulationOptions& options);
// The smallest rtol SimulationOptions accepts.
inline constexpr double kMinRtol = 1e-14;
// CVODE at options.rtol, checked against a second run at rtol/10 (atol likewise): the result of the
// first run with error_estimate = max |Δ link torque| / max |link torque| between the two, a
// measured figure where SimulateCvode reports only the tolerance asked for. Costs both runs.
// Below rtol 1e-13 there is no tighter run: plain SimulateCvode.
SimulationResult SimulateCvodeChecked(const Model& model, const SimulationOptions& options);
// The accuracy a solver's result is expected to reach, relative to peak: beyond it the CLI warns.
inline constexpr double kExactErrorTarget = 1e-9;
inline constexpr double kCvodeErrorTarget = 1e-6;

// Dynamic factor of each scene link (SPEC §2.5): Kd = max_t |m(t)| / |m_s| over the samples, m_s
// the static torque under the final loads. kd is NaN when |m_s| is zero to roundoff (Kd undefined).
// Reads result.peak_abs_torque_Nm / peak_time_s (so it works without kept samples); a result
// without peak fields (built by hand) falls back to the link_torque_Nm columns.
struct DynamicFactor {
  std::string link;
  double peak_torque_Nm = 0.0;
  double peak_time_s = 0.0;
  double static_torque_Nm = 0.0;
  double kd = 0.0;
};
std::vector<DynamicFactor> DynamicFactors(const Model& model, const SimulationResult& result);

// The table printed by `millkit simulate`.
std::string FormatDynamicFactorTable(const std::vector<DynamicFactor>& factors);

}  // namespace millkit::driveline
