// Coupling stiffness (and damping) optimisation with NLopt (SPEC.md §5, issue 5).
//
// Problem: choose the variables x (stiffness and/or damping of chosen links, within bounds) to
//   minimise  Kd_max(x) = max over the counted links of Kd(x) = max_t |m(t)| / |m_s|   (SPEC §2.5)
//   subject to  twist_l = b_l/2 + |T_rated,l| / c_l ≤ max_twist_l   (static twist at rated torque)
//               f_1(x) ≥ min_frequency                              (lowest natural frequency)
// twist_l is the quasi-static twist of the model (SPEC §2.4: the rest flank plus the elastic
// twist) at the rated torque; f_1 is the lowest elastic mode with every gap closed
// (millkit/driveline/natural_frequencies.h).
//
// How: the twist constraint of a link whose stiffness is a variable is monotone in that one
// stiffness, so it is imposed exactly as a lower bound c_l ≥ |T| / (max_twist − b/2) (rounded up
// to the first double that satisfies it); on a link whose stiffness is fixed it is checked once.
// Variables are mapped to the unit cube (stiffness on a log scale by default, damping linear).
//   1. Global stage: NLopt GN_DIRECT_L over the cube. A point violating the frequency limit is not
//      simulated; its objective is kInfeasibleObjective + the relative violation (a penalty far
//      above any Kd, sloped towards feasibility). A failed simulation scores kFailedObjective.
//   2. Local polish: LN_BOBYQA (or LN_COBYLA) from the best feasible point on the same objective.
// Every evaluation is recorded; the answer is the best FEASIBLE evaluated point over both stages,
// the scene as given (when it lies inside the bounds) and the points NLopt returns, each
// re-evaluated from scratch (NLopt's returned value is not trusted: 2.7 throws roundoff_limited
// at good points and can return a point it did not score). Objective wrappers are noexcept.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "millkit/driveline/scene.h"
#include "millkit/driveline/simulation.h"
#include "millkit/optimize/algorithm.h"
#include "millkit/sweep/sample_plan.h"
#include "millkit/sweep/sweep_case.h"

namespace millkit::coupling {

inline constexpr double kInfeasibleObjective = 1e6;
inline constexpr double kFailedObjective = 2e6;

struct TwistLimit {
  int link = -1;
  double max_twist_rad = 0.0;    // > b/2
  double rated_torque_Nm = 0.0;  // |T| used; > 0
};

struct CouplingProblem {
  std::string file;  // configuration file, for messages
  // Each a `<link>.stiffness` or `<link>.damping` parameter with its bounds and scale.
  std::vector<sweep::SweepDimension> variables;
  std::vector<int> counted_links;  // Kd counts on these scene links (each with m_s != 0)
  std::vector<TwistLimit> twist_limits;
  std::optional<double> min_frequency_Hz;
};

struct CouplingOptions {
  optimize::Algorithm global_algorithm = optimize::Algorithm::kGnDirectL;
  int global_evaluations = 200;
  // kLnBobyqa, kLnCobyla, or none (local_evaluations = 0).
  optimize::Algorithm local_algorithm = optimize::Algorithm::kLnBobyqa;
  int local_evaluations = 100;
  double xtol = 1e-5;        // on the unit cube (relative to each variable's (log) range)
  double local_step = 0.05;  // initial step of the polish, on the unit cube
  driveline::SimulationOptions simulation = sweep::StudySimulationOptions();

  // Throws InputError naming the broken rule.
  void Validate() const;
};

// One evaluated point.
struct CouplingPoint {
  std::vector<double> values;  // per variable, in its unit
  sweep::CaseResult simulation;
  double kd_max = 0.0;            // over the counted links; NaN unless the simulation succeeded
  std::vector<double> twist_rad;  // per twist limit
  double lowest_frequency_Hz = 0.0;
  // Σ relative violations: max(0, twist/max_twist − 1) + max(0, 1 − f_1/min_frequency).
  double violation = 0.0;
  bool constraints_met = false;  // violation == 0: every limit holds exactly
  bool feasible() const { return constraints_met && simulation.success; }
};

struct CouplingSummary {
  std::string global_algorithm;
  std::string local_algorithm;  // "none" when skipped
  std::string global_result;    // NLopt's verdict (or the exception it threw)
  std::string local_result;
  int global_evaluations = 0;
  int local_evaluations = 0;
  int simulations = 0;  // evaluations that ran the simulator
  int failed_simulations = 0;
  int infeasible_evaluations = 0;   // rejected by the frequency limit without simulating
  double nlopt_value = 0.0;         // NLopt's own optimum value of the last stage (not trusted)
  bool found = false;               // a feasible point was found
  std::string chosen_from;          // global | local | scene | nlopt-returned
  double recheck_difference = 0.0;  // |Kd_max re-evaluated − Kd_max recorded| at the answer
  double wall_time_s = 0.0;
  std::string message;  // why nothing was found

  std::string BriefReport() const;
};

struct CouplingResult {
  CouplingPoint best;                  // valid when summary.found
  std::optional<CouplingPoint> scene;  // the scene as given, when inside the bounds
  std::vector<double> lower;           // effective bounds (after the twist limits)
  std::vector<double> upper;
  CouplingSummary summary;
};

// Validates the problem against the scene. Throws InputError (naming problem.file) when: a
// variable is not a stiffness or damping, a counted link has m_s = 0 (Kd undefined), a twist limit
// leaves no stiffness inside the bounds or fails on a link whose stiffness is fixed, the frequency
// limit is not met even at the stiffest bounds, or the model cannot be built at the stiffest
// bounds (e.g. the sample rate cannot resolve the fastest mode there).
// Returns the effective bounds (lower, upper) per variable.
std::pair<std::vector<double>, std::vector<double>> EffectiveBounds(const driveline::Scene& scene,
                                                                    const CouplingProblem& problem);

// Evaluates the problem at `values` (one per variable): constraints, and the simulation when
// `simulate_if_infeasible` or the constraints hold.
CouplingPoint EvaluateCoupling(const driveline::Scene& scene, const CouplingProblem& problem,
                               const std::vector<double>& values,
                               const driveline::SimulationOptions& simulation,
                               bool simulate_if_infeasible = true);

// Runs both stages. Bad input throws InputError; finding no feasible point is reported in the
// summary (found = false), not thrown.
CouplingResult OptimizeCoupling(const driveline::Scene& scene, const CouplingProblem& problem,
                                const CouplingOptions& options);

// One point of the Kd-vs-variable curve around the answer.
struct CurvePoint {
  int variable = -1;  // which variable moves; the others stay at the answer
  CouplingPoint point;
};

struct CurveOptions {
  int points = 41;     // per variable, plus the answer itself
  double width = 0.5;  // fraction of each variable's (log) range on each side of the answer
  int threads = 1;
  void Validate() const;  // points in [2, 10000], width in (0, 1], threads in [1, 256]
};

// For every variable: `points` values evenly spaced on its scale over the configured bounds
// ∩ [answer − width, answer + width] (unit cube), and the answer; sorted by value.
std::vector<CurvePoint> CouplingCurve(const driveline::Scene& scene, const CouplingProblem& problem,
                                      const std::vector<double>& answer, const CurveOptions& curve,
                                      const driveline::SimulationOptions& simulation);

}  // namespace millkit::coupling
