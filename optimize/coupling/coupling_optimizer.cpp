#include "millkit/optimize/coupling/coupling_optimizer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <limits>

#include "millkit/driveline/natural_frequencies.h"
#include "millkit/io/input_error.h"
#include "millkit/io/number_format.h"
#include "millkit/sweep/sweep_runner.h"
#include "optimize/nlopt_algorithm.h"

namespace millkit::coupling {
namespace {

using driveline::LowestNaturalFrequencyHz;
using driveline::SceneParameter;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::vector<SceneParameter> Parameters(const CouplingProblem& problem) {
  std::vector<SceneParameter> parameters;
  for (const auto& v : problem.variables) parameters.push_back(v.parameter);
  return parameters;
}

// Twist, frequency and violation of `scene` (the variables already set on it).
void ScoreConstraints(const driveline::Scene& scene, const CouplingProblem& problem,
                      CouplingPoint* point) {
  point->violation = 0.0;
  point->twist_rad.clear();
  for (const auto& limit : problem.twist_limits) {
    const driveline::Link& link = scene.links[limit.link];
    const double twist = driveline::QuasiStaticTwist(link, limit.rated_torque_Nm);
    point->twist_rad.push_back(twist);
    point->violation += std::max(0.0, twist / limit.max_twist_rad - 1.0);
  }
  point->lowest_frequency_Hz = LowestNaturalFrequencyHz(scene);
  if (problem.min_frequency_Hz) {
    point->violation += std::max(0.0, 1.0 - point->lowest_frequency_Hz / *problem.min_frequency_Hz);
  }
  point->constraints_met = point->violation == 0.0;
}

void ScoreSimulation(const CouplingProblem& problem, sweep::CaseResult simulation,
                     CouplingPoint* point) {
  point->simulation = std::move(simulation);
  point->kd_max = kNaN;
  if (!point->simulation.success) return;
  double kd_max = 0.0;
  for (int l : problem.counted_links) kd_max = std::max(kd_max, point->simulation.kd[l]);
  point->kd_max = kd_max;
}

// Whether a beats b as an answer: feasible first, then the lower Kd_max.
bool Better(const CouplingPoint& a, const std::optional<CouplingPoint>& b) {
  if (!a.feasible()) return false;
  return !b || !b->feasible() || a.kd_max < b->kd_max;
}

// State shared with the NLopt objective (a C callback underneath: nothing may throw out of it).
struct Search {
  const driveline::Scene* scene = nullptr;
  const CouplingProblem* problem = nullptr;
  const CouplingOptions* options = nullptr;
  std::vector<sweep::SweepDimension> box;  // variables with the effective bounds
  nlopt::opt* running = nullptr;
  const char* stage = "global";
  int* stage_evaluations = nullptr;
  CouplingSummary* summary = nullptr;
  std::optional<CouplingPoint> best;
  std::vector<double> best_unit;
  std::string best_stage;
  std::exception_ptr error;

  std::vector<double> Values(const double* u) const {
    std::vector<double> values(box.size());
    for (size_t i = 0; i < box.size(); ++i) values[i] = box[i].FromUnit(u[i]);
    return values;
  }
};

double Objective(unsigned n, const double* u, double* /*grad: derivative-free*/,
                 void* data) noexcept {
  auto* s = static_cast<Search*>(data);
  try {
    ++*s->stage_evaluations;
    const CouplingPoint point =
        EvaluateCoupling(*s->scene, *s->problem, s->Values(u), s->options->simulation, false);
    if (!point.constraints_met) {
      ++s->summary->infeasible_evaluations;
      return kInfeasibleObjective + point.violation;
    }
    ++s->summary->simulations;
    if (!point.simulation.success) {
      ++s->summary->failed_simulations;
      return kFailedObjective;
    }
    if (Better(point, s->best)) {
      s->best = point;
      s->best_unit.assign(u, u + n);
      s->best_stage = s->stage;
    }
    return point.kd_max;
  } catch (...) {
    if (!s->error) s->error = std::current_exception();
    s->running->force_stop();
    return kFailedObjective;
  }
}

// Runs one stage; NLopt's verdict, or the exception it threw, as text. x keeps NLopt's point.
std::string RunStage(Search* search, nlopt::opt& opt, std::vector<double>& x, double* value) {
  search->running = &opt;
  opt.set_min_objective(Objective, search);
  std::string verdict;
  try {
    verdict = nlopt_result_to_string(static_cast<nlopt_result>(opt.optimize(x, *value)));
  } catch (const nlopt::roundoff_limited&) {
    verdict = "ROUNDOFF_LIMITED (exception)";
  } catch (const nlopt::forced_stop&) {
    verdict = "FORCED_STOP (exception)";
  } catch (const std::exception& e) {
    verdict = std::string("FAILURE (exception: ") + e.what() + ")";
  }
  if (search->error) std::rethrow_exception(search->error);
  return verdict;
}

}  // namespace

void CouplingOptions::Validate() const {
  if (global_evaluations < 1) throw InputError("global_evaluations must be >= 1");
  if (local_evaluations < 0) throw InputError("local_evaluations must be >= 0");
  if (local_evaluations > 0 && local_algorithm != optimize::Algorithm::kLnBobyqa &&
      local_algorithm != optimize::Algorithm::kLnCobyla) {
    throw InputError("the local polish must be LN_BOBYQA or LN_COBYLA");
  }
  if (!(xtol > 0.0 && xtol < 1.0)) throw InputError("xtol must lie in (0, 1)");
  if (!(local_step > 0.0 && local_step <= 0.5)) throw InputError("local_step must lie in (0, 0.5]");
  simulation.Validate();
}

void CurveOptions::Validate() const {
  if (points < 2 || points > 10000) throw InputError("curve points must lie in [2, 10000]");
  if (!(width > 0.0 && width <= 1.0)) throw InputError("curve width must lie in (0, 1]");
  sweep::RunnerOptions{threads}.Validate();
}

std::string CouplingSummary::BriefReport() const {
  char line[512];
  std::snprintf(line, sizeof(line),
                "%s (%d evaluations, %s) + %s (%d evaluations, %s): %s; %d simulations "
                "(%d failed), %d rejected by the frequency limit, %.3g s",
                global_algorithm.c_str(), global_evaluations, global_result.c_str(),
                local_algorithm.c_str(), local_evaluations, local_result.c_str(),
                found ? ("best from " + chosen_from).c_str() : ("NOT FOUND: " + message).c_str(),
                simulations, failed_simulations, infeasible_evaluations, wall_time_s);
  return line;
}

CouplingPoint EvaluateCoupling(const driveline::Scene& scene, const CouplingProblem& problem,
                               const std::vector<double>& values,
                               const driveline::SimulationOptions& simulation,
                               bool simulate_if_infeasible) {
  CouplingPoint point;
  point.values = values;
  const driveline::Scene at = sweep::WithValues(scene, Parameters(problem), values);
  ScoreConstraints(at, problem, &point);
  point.kd_max = kNaN;
  point.simulation.message = "not simulated: constraints violated";
  if (point.constraints_met || simulate_if_infeasible) {
    ScoreSimulation(problem, sweep::SimulateCase(at, simulation), &point);
  }
  return point;
}

std::pair<std::vector<double>, std::vector<double>> EffectiveBounds(
    const driveline::Scene& scene, const CouplingProblem& problem) {
  const std::string& file = problem.file;
  if (problem.variables.empty()) throw InputError(file + ": no [[variable]] to optimise");
  if (problem.counted_links.empty()) throw InputError(file + ": no link counts in the objective");
  std::vector<double> lower, upper;
  for (const auto& v : problem.variables) {
    if (v.parameter.kind != SceneParameter::Kind::kStiffness &&
        v.parameter.kind != SceneParameter::Kind::kDamping) {
      throw InputError(file + ": variable '" + v.parameter.name +
                       "': only <link>.stiffness and <link>.damping can be optimised");
    }
    lower.push_back(v.lower);
    upper.push_back(v.upper);
  }
  for (const auto& limit : problem.twist_limits) {
    const driveline::Link& link = scene.links[limit.link];
    const double half_gap = 0.5 * link.backlash_rad;
    const std::string what = file + ": [[twist_limit]] on link '" + link.name + "': ";
    if (!(limit.max_twist_rad > half_gap)) {
      throw InputError(what + "max_twist " + FormatNumber(limit.max_twist_rad) +
                       " rad is not above the half gap b/2 = " + FormatNumber(half_gap) +
                       " rad, so no stiffness meets it");
    }
    int variable = -1;
    for (size_t i = 0; i < problem.variables.size(); ++i) {
      const auto& p = problem.variables[i].parameter;
      if (p.kind == SceneParameter::Kind::kStiffness && p.index == limit.link) variable = int(i);
    }
    if (variable < 0) {
      const double twist = driveline::QuasiStaticTwist(link, limit.rated_torque_Nm);
      if (twist > limit.max_twist_rad) {
        throw InputError(what + "the static twist is " + FormatNumber(twist) + " rad > max_twist " +
                         FormatNumber(limit.max_twist_rad) +
                         " rad and the link's stiffness is not a variable");
      }
      continue;
    }
    // b/2 + T/c <= max  <=>  c >= T / (max − b/2); rounded up until the twist itself holds.
    double c_min = limit.rated_torque_Nm / (limit.max_twist_rad - half_gap);
    while (half_gap + limit.rated_torque_Nm / c_min > limit.max_twist_rad) {
      c_min = std::nextafter(c_min, std::numeric_limits<double>::infinity());
    }
    lower[variable] = std::max(lower[variable], c_min);
    if (lower[variable] > upper[variable]) {
      throw InputError(what + "needs stiffness >= " + FormatNumber(c_min) +
                       " N*m/rad, above the variable's upper bound " +
                       FormatNumber(upper[variable]));
    }
  }
  // The stiffest corner: the highest modes and the lowest frequency's best case.
  const driveline::Scene corner = sweep::WithValues(scene, Parameters(problem), upper);
  if (problem.min_frequency_Hz) {
    const double f1 = LowestNaturalFrequencyHz(corner);
    if (f1 < *problem.min_frequency_Hz) {
      throw InputError(file + ": [frequency_limit] key 'min_frequency': " +
                       FormatNumber(*problem.min_frequency_Hz) +
                       " Hz cannot be met: the lowest natural frequency at the upper bounds is " +
                       FormatNumber(f1) + " Hz");
    }
  }
  // Static torques do not depend on stiffness or damping: one run tells which Kd are undefined.
  const sweep::CaseResult probe = sweep::SimulateCase(corner, sweep::StudySimulationOptions());
  if (!probe.success) {
    throw InputError(file +
                     ": [[variable]] key 'upper': the scene with every variable at its "
                     "upper bound cannot be simulated: " +
                     probe.message);
  }
  for (int l : problem.counted_links) {
    if (std::isnan(probe.kd[l])) {
      throw InputError(file + ": [objective] key 'links' (default: every link): Kd of link '" +
                       scene.links[l].name +
                       "' is undefined: its static torque under the final loads is " +
                       FormatNumber(probe.static_torque_Nm[l]) + " N*m; leave it out");
    }
  }
  return {lower, upper};
}

CouplingResult OptimizeCoupling(const driveline::Scene& scene, const CouplingProblem& problem,
                                const CouplingOptions& options) {
  const auto started = std::chrono::steady_clock::now();
  options.Validate();
  CouplingResult result;
  std::tie(result.lower, result.upper) = EffectiveBounds(scene, problem);
  const int n = static_cast<int>(problem.variables.size());
  CouplingSummary& summary = result.summary;

  Search search;
  search.scene = &scene;
  search.problem = &problem;
  search.options = &options;
  search.summary = &summary;
  search.box = problem.variables;
  for (int i = 0; i < n; ++i) {
    search.box[i].lower = result.lower[i];
    search.box[i].upper = result.upper[i];
  }

  // 1. Global stage over the unit cube, from its centre.
  nlopt::opt global(optimize::ToNlopt(options.global_algorithm), n);
  global.set_lower_bounds(std::vector<double>(n, 0.0));
  global.set_upper_bounds(std::vector<double>(n, 1.0));
  global.set_maxeval(options.global_evaluations);
  global.set_xtol_abs(options.xtol);
  std::vector<double> x(n, 0.5);
  search.stage = "global";
  search.stage_evaluations = &summary.global_evaluations;
  summary.global_algorithm = nlopt_algorithm_to_string(
      static_cast<nlopt_algorithm>(optimize::ToNlopt(options.global_algorithm)));
  summary.global_result = RunStage(&search, global, x, &summary.nlopt_value);

  // 2. Local polish from the best feasible point (else from where the global stage ended).
  summary.local_algorithm = "none";
  summary.local_result = "skipped";
  if (options.local_evaluations > 0) {
    nlopt::opt local(optimize::ToNlopt(options.local_algorithm), n);
    local.set_lower_bounds(std::vector<double>(n, 0.0));
    local.set_upper_bounds(std::vector<double>(n, 1.0));
    local.set_maxeval(options.local_evaluations);
    local.set_xtol_abs(options.xtol);
    if (search.best) x = search.best_unit;
    std::vector<double> step(n);
    for (int i = 0; i < n; ++i) {
      // BOBYQA needs the first step to fit between x and the bounds on at least one side.
      step[i] = std::min(options.local_step, std::max(x[i], 1.0 - x[i]));
    }
    local.set_initial_step(step);
    search.stage = "local";
    search.stage_evaluations = &summary.local_evaluations;
    summary.local_algorithm = nlopt_algorithm_to_string(
        static_cast<nlopt_algorithm>(optimize::ToNlopt(options.local_algorithm)));
    summary.local_result = RunStage(&search, local, x, &summary.nlopt_value);
  }

  // 3. The answer, re-evaluated: the best recorded point, NLopt's last returned point, and the
  // scene as given when it lies inside the bounds.
  std::optional<CouplingPoint> answer;
  if (search.best) {
    answer = EvaluateCoupling(scene, problem, search.best->values, options.simulation);
    summary.recheck_difference = std::abs(answer->kd_max - search.best->kd_max);
    summary.chosen_from = search.best_stage;
    if (!answer->feasible()) answer.reset();  // cannot happen for a deterministic simulator
  }
  for (double& u : x) u = std::clamp(u, 0.0, 1.0);
  const CouplingPoint returned =
      EvaluateCoupling(scene, problem, search.Values(x.data()), options.simulation);
  if (Better(returned, answer)) {
    answer = returned;
    summary.chosen_from = "nlopt-returned";
  }
  std::vector<double> given(n);
  bool inside = true;
  for (int i = 0; i < n; ++i) {
    given[i] = problem.variables[i].parameter.Get(scene);
    inside = inside && given[i] >= result.lower[i] && given[i] <= result.upper[i];
  }
  if (inside) {
    result.scene = EvaluateCoupling(scene, problem, given, options.simulation);
    if (Better(*result.scene, answer)) {
      answer = result.scene;
      summary.chosen_from = "scene";
    }
  }
  summary.found = answer.has_value();
  if (answer) {
    result.best = *answer;
  } else {
    summary.message = "no feasible point with a successful simulation among " +
                      std::to_string(summary.global_evaluations + summary.local_evaluations) +
                      " evaluations";
  }
  summary.wall_time_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  return result;
}

std::vector<CurvePoint> CouplingCurve(const driveline::Scene& scene, const CouplingProblem& problem,
                                      const std::vector<double>& answer, const CurveOptions& curve,
                                      const driveline::SimulationOptions& simulation) {
  curve.Validate();
  std::vector<int> moving;
  sweep::CaseList cases;
  for (size_t v = 0; v < problem.variables.size(); ++v) {
    const auto& d = problem.variables[v];
    const double centre = d.ToUnit(answer[v]);
    const double lo = std::max(0.0, centre - curve.width);
    const double hi = std::min(1.0, centre + curve.width);
    std::vector<double> values{answer[v]};
    for (int i = 0; i < curve.points; ++i) {
      values.push_back(d.FromUnit(lo + (hi - lo) * i / (curve.points - 1)));
    }
    std::sort(values.begin(), values.end());
    values.erase(std::unique(values.begin(), values.end()), values.end());
    for (double value : values) {
      cases.push_back(answer);
      cases.back()[v] = value;
      moving.push_back(static_cast<int>(v));
    }
  }
  sweep::RunnerOptions runner;
  runner.threads = curve.threads;
  const auto simulated = sweep::RunCases(
      sweep::SceneCaseFunction(scene, Parameters(problem), simulation), cases, runner);
  std::vector<CurvePoint> points(cases.size());
  for (size_t c = 0; c < cases.size(); ++c) {
    points[c].variable = moving[c];
    CouplingPoint& p = points[c].point;
    p.values = cases[c];
    ScoreConstraints(sweep::WithValues(scene, Parameters(problem), cases[c]), problem, &p);
    ScoreSimulation(problem, simulated[c], &p);
  }
  return points;
}

}  // namespace millkit::coupling
