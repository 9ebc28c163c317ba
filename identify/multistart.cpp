#include "identify/multistart.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <numeric>
#include <random>
#include <vector>

#include "identify/verdict.h"
#include "millkit/io/number_format.h"

namespace millkit::identify {
namespace {

ceres::Problem::Options ProblemOptions() {
  ceres::Problem::Options options;
  options.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  return options;
}

// Impact timing: what a short window after the onset sees well.
bool TimingParameter(const FreeParameter& free) {
  using Kind = driveline::SceneParameter::Kind;
  const auto kind = free.parameter.kind;
  return kind == Kind::kBacklash || kind == Kind::kGapPosition || kind == Kind::kBiteTime;
}

// Whether two points agree within `distance` in every unit coordinate.
bool SamePoint(const std::vector<double>& a, const std::vector<double>& b, double distance) {
  for (size_t i = 0; i < a.size(); ++i) {
    if (!(std::abs(a[i] - b[i]) <= distance)) return false;
  }
  return true;
}

// A step that changes the cost (½ χ² in noise units) by less than this is a stall.
constexpr double kStalledCostChange = 1e-3;

}  // namespace

double FloorCost(const FitOptions& options) {
  // No creep stop without the stop it belongs to (CloseEnough is attached only then): no floor.
  if (!(options.remaining_step_se > 0.0)) return 0.0;
  return options.creep_iterations * kStalledCostChange;
}

namespace {

// Ends Levenberg–Marquardt where the Gauss–Newton step still to go from the current point is
// below options.remaining_step_se standard errors, or below options.rough_step_se after a step
// that stalled (FitOptions). The current point's Jacobian is the latest one evaluated: Ceres
// evaluates it at the start and after every accepted step, and only the cost at a rejected one.
// It also ends a creep: the cost down by no more than creep_iterations × the stall's change over
// the last creep_iterations iterations, where the Gauss–Newton step promises more than the valley
// gives (a valley that curves, or a parameter the record hardly sees).
class CloseEnough final : public ceres::IterationCallback {
 public:
  CloseEnough(const ProjectedResidual& residual, const FitOptions& options)
      : residual_(residual), options_(options) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& summary) override {
    const double left = residual_.remaining_step_se();
    const bool stalled =
        summary.iteration > 0 && std::abs(summary.cost_change) <= kStalledCostChange;
    if ((summary.step_is_successful && left <= options_.remaining_step_se) ||
        (stalled && left <= options_.rough_step_se)) {
      return ceres::SOLVER_TERMINATE_SUCCESSFULLY;
    }
    costs_.push_back(summary.cost);
    const auto window = static_cast<size_t>(options_.creep_iterations);
    if (window > 0 && costs_.size() > window &&
        costs_[costs_.size() - 1 - window] - summary.cost <=
            static_cast<double>(window) * kStalledCostChange) {
      crept_ = true;
      return ceres::SOLVER_TERMINATE_SUCCESSFULLY;
    }
    return ceres::SOLVER_CONTINUE;
  }
  bool crept() const { return crept_; }

 private:
  const ProjectedResidual& residual_;
  const FitOptions& options_;
  std::vector<double> costs_;  // the current point's cost after each iteration
  bool crept_ = false;
};

// Reports each finished iteration to the residual (ProjectedResidual::EndEarly), and, given a
// known minimum, ends Levenberg–Marquardt at the first current point within options.rejoin_se of
// it (the length of the difference in φ under the minimum's precision) whose χ² (twice the
// fixed-weight cost) is not below the minimum's by more than 1. The residual tests every accepted
// point before its Jacobian (which the fit then never reads); the start is tested here.
class EarlyEnd final : public ceres::IterationCallback {
 public:
  EarlyEnd(const ProjectedResidual& residual, const FitOptions& options, const LocalFit* known)
      : residual_(residual), options_(options), known_(known) {
    if (known == nullptr) return;
    phi_.resize(static_cast<Eigen::Index>(known->u.size()));
    for (size_t i = 0; i < known->u.size(); ++i) {
      phi_[static_cast<Eigen::Index>(i)] = ParameterMap::AngleFromUnit(known->u[i]);
    }
  }
  bool Rejoins(const double* phi, double cost) const {
    const Eigen::VectorXd d = Eigen::Map<const Eigen::VectorXd>(phi, phi_.size()) - phi_;
    return d.dot(known_->precision * d) <= options_.rejoin_se * options_.rejoin_se &&
           2.0 * (cost - known_->cost) >= -1.0;
  }
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& summary) override {
    residual_.IterationFinished(summary.iteration);
    const std::vector<double>& at = residual_.jacobian_point();
    if (residual_.stopped() ||
        (known_ != nullptr && summary.iteration == 0 &&
         static_cast<Eigen::Index>(at.size()) == phi_.size() && Rejoins(at.data(), summary.cost))) {
      rejoined_ = true;
      return ceres::SOLVER_TERMINATE_SUCCESSFULLY;
    }
    return ceres::SOLVER_CONTINUE;
  }
  bool rejoined() const { return rejoined_; }

 private:
  const ProjectedResidual& residual_;
  const FitOptions& options_;
  const LocalFit* known_;
  Eigen::VectorXd phi_;
  bool rejoined_ = false;
};

// The starts (0 … starts − 1) some fit of which ends within χ² 1 of minima[best] (fixed weights).
int StartsAtBest(const std::vector<LocalFit>& minima, int best, int starts) {
  std::vector<bool> reached(starts, false);
  for (const auto& fit : minima) {
    if (fit.usable && fit.start >= 0 && fit.start < starts &&
        2.0 * (fit.cost - minima[best].cost) <= 1.0) {
      reached[fit.start] = true;
    }
  }
  return static_cast<int>(std::count(reached.begin(), reached.end(), true));
}

}  // namespace

std::vector<std::vector<double>> ScanStarts(const FitModel& model, const FitConfig& config,
                                            const FitOptions& options,
                                            const std::vector<double>& start, int count,
                                            int* evaluated) {
  std::vector<int> scanned;
  for (int i = 0; i < model.parameters(); ++i) {
    if (model.free(i).scan) scanned.push_back(i);
  }
  const int points = scanned.empty() ? 0 : config.scan_points;
  std::mt19937_64 random(config.seed);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::vector<std::vector<double>> lattice(scanned.size(), std::vector<double>(points));
  for (auto& column : lattice) {
    for (int k = 0; k < points; ++k) column[k] = (k + uniform(random)) / points;
    std::shuffle(column.begin(), column.end(), random);
  }
  // Point 0 is the start itself, point k + 1 the lattice's k-th.
  const auto point = [&](int k) {
    std::vector<double> u = start;
    if (k >= 0) {
      for (size_t s = 0; s < scanned.size(); ++s) u[scanned[s]] = lattice[s][k];
    }
    return u;
  };
  const std::vector<double> costs = MapOverCopies<double>(
      model, options.threads, points + 1,
      [&](const FitModel& copy, int i) { return copy.ProjectedCost(point(i - 1).data()); });
  std::vector<std::pair<double, std::vector<double>>> candidates;
  for (int k = -1; k < points; ++k) {
    if (std::isfinite(costs[k + 1])) candidates.emplace_back(costs[k + 1], point(k));
  }
  *evaluated = points;
  std::stable_sort(candidates.begin(), candidates.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  const auto distance = [&](const std::vector<double>& a, const std::vector<double>& b) {
    double sum = 0.0;
    for (const int s : scanned) sum += (a[s] - b[s]) * (a[s] - b[s]);
    return std::sqrt(sum / std::max<size_t>(1, scanned.size()));
  };
  std::vector<std::vector<double>> best;
  for (const auto& [cost, u] : candidates) {
    if (static_cast<int>(best.size()) >= count) break;
    // Structured bindings are captured by name only from clang 16 on (P1091); clang-14 builds
    // the sanitizer and fuzzing targets.
    const bool distinct = std::all_of(best.begin(), best.end(), [&, &u = u](const auto& other) {
      return distance(u, other) >= options.distinct_start;
    });
    if (distinct) best.push_back(u);
  }
  return best;
}

LocalFit Refine(const FitModel& model, const FitOptions& options, std::vector<double> u,
                bool final_stage, int iterations, const std::vector<int>& frozen,
                const LocalFit* known) {
  ProjectedResidual residual(model, options.derivative_step, options.derivatives, frozen);
  ceres::Problem problem(ProblemOptions());
  std::vector<double> phi(u.size());
  for (size_t i = 0; i < u.size(); ++i) phi[i] = ParameterMap::AngleFromUnit(u[i]);
  LocalFit fit;
  if (phi.empty()) {
    // Nothing but gains and offsets: the projection is the whole fit.
    fit.u = std::move(u);
    fit.cost = model.ProjectedCost(fit.u.data());
    fit.usable = fit.converged = std::isfinite(fit.cost);
    return fit;
  }
  problem.AddResidualBlock(&residual, nullptr, phi.data());
  if (!frozen.empty()) {
    if (static_cast<int>(frozen.size()) == model.parameters()) {
      problem.SetParameterBlockConstant(phi.data());
    } else {
      problem.SetManifold(phi.data(), new ceres::SubsetManifold(model.parameters(), frozen));
    }
  }
  ceres::Solver::Options solver;
  solver.linear_solver_type = ceres::DENSE_QR;
  solver.max_num_iterations = final_stage ? options.max_iterations : iterations;
  solver.function_tolerance = final_stage ? options.function_tolerance : 1e-6;
  solver.parameter_tolerance = final_stage ? options.parameter_tolerance : 1e-6;
  solver.gradient_tolerance = 1e-20;
  solver.num_threads = 1;  // one residual block: the workers are the search's (options.threads)
  solver.logging_type = ceres::SILENT;
  // The rejoin test first: where both stop the fit, it is the known minimum.
  const bool rejoin = known != nullptr && known->precision.size() > 0 && options.rejoin_se > 0.0;
  EarlyEnd early_end(residual, options, rejoin ? known : nullptr);
  residual.EndEarly(solver.max_num_iterations,
                    rejoin ? std::function<bool(const double*, double)>(
                                 [&early_end](const double* phi, double cost) {
                                   return early_end.Rejoins(phi, cost);
                                 })
                           : nullptr);
  solver.callbacks.push_back(&early_end);
  CloseEnough close_enough(residual, options);
  if (final_stage && frozen.empty() && options.remaining_step_se > 0.0) {
    residual.MeasureRemainingStep();
    solver.callbacks.push_back(&close_enough);
  }
  ceres::Solve(solver, &problem, &fit.summary);
  if (early_end.rejoined()) {
    fit.summary.termination_type = ceres::CONVERGENCE;
    fit.summary.message = "came back to a minimum found before (within " +
                          ShortNumber(options.rejoin_se) + " standard errors)";
    fit.u = known->u;
    fit.cost = known->cost;
    fit.precision = known->precision;
    fit.usable = known->usable;
    fit.converged = known->converged;
    fit.rejoined = true;
    return fit;
  }
  if (fit.summary.termination_type == ceres::USER_SUCCESS) {
    // Converged by the statistical test: reported as Ceres' own convergence.
    fit.summary.termination_type = ceres::CONVERGENCE;
    fit.summary.message = close_enough.crept()
                              ? "creeping: the cost fell by no more than " +
                                    ShortNumber(FloorCost(options)) + " over the last " +
                                    std::to_string(options.creep_iterations) + " iterations"
                              : "the Gauss-Newton step left is below " +
                                    ShortNumber(options.remaining_step_se) + " standard errors (" +
                                    ShortNumber(options.rough_step_se) + " after a stalled step)";
  }
  fit.u.resize(phi.size());
  for (size_t i = 0; i < phi.size(); ++i) fit.u[i] = ParameterMap::UnitFromAngle(phi[i]);
  if (residual.jacobian_point() == phi) fit.precision = residual.precision();
  fit.usable = fit.summary.IsSolutionUsable() && std::isfinite(fit.summary.final_cost);
  fit.converged = fit.summary.termination_type == ceres::CONVERGENCE;
  fit.cost = fit.usable ? fit.summary.final_cost : std::numeric_limits<double>::infinity();
  if (!fit.usable && fit.summary.termination_type == ceres::FAILURE) {
    // Ceres stops when the Jacobian cannot be evaluated at an accepted point (a simulation the
    // solver rejects at a finite-difference probe). The accepted point itself is a valid,
    // improved answer; the next stage carries on from it. It has not converged.
    fit.cost = model.ProjectedCost(fit.u.data());
    fit.usable = std::isfinite(fit.cost);
  }
  return fit;
}

std::vector<double> ContinuationStages(const FitModel& model, const FitOptions& options) {
  std::vector<double> stages;
  for (double divisor = options.first_stage_divisor; divisor > 1.0 + 1e-9;
       divisor /= options.continuation_ratio) {
    if (model.FewestSamples(divisor) >= kMinRecordSamples) stages.push_back(divisor);
  }
  stages.push_back(1.0);
  return stages;
}

std::vector<std::vector<double>> PreselectStarts(FitModel* model, const FitOptions& options,
                                                 const std::vector<std::vector<double>>& points,
                                                 int count) {
  const std::vector<double> stages = ContinuationStages(*model, options);
  if (stages.size() < 2 || static_cast<int>(points.size()) <= count) return points;
  model->SetStage(stages.front());
  std::vector<int> not_timing;
  for (int i = 0; i < model->parameters(); ++i) {
    if (!TimingParameter(model->free(i))) not_timing.push_back(i);
  }
  if (static_cast<int>(not_timing.size()) == model->parameters()) not_timing.clear();
  std::vector<LocalFit> fits = MapOverCopies<LocalFit>(
      *model, options.threads, static_cast<int>(points.size()), [&](const FitModel& copy, int i) {
        return Refine(copy, options, points[i], false, options.stage_iterations,
                      options.timing_only_stages > 0 ? not_timing : std::vector<int>{});
      });
  std::vector<std::pair<double, std::vector<double>>> fitted;
  for (auto& fit : fits) {
    if (fit.usable) fitted.emplace_back(fit.cost, std::move(fit.u));
  }
  model->SetStage(1.0);
  std::stable_sort(fitted.begin(), fitted.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<std::vector<double>> best;
  for (const auto& [cost, u] : fitted) {
    if (static_cast<int>(best.size()) >= count) break;
    const bool distinct = std::all_of(best.begin(), best.end(), [&, &u = u](const auto& other) {
      double sum = 0.0;
      for (size_t s = 0; s < u.size(); ++s) sum += (u[s] - other[s]) * (u[s] - other[s]);
      return std::sqrt(sum / std::max<size_t>(1, u.size())) >= options.distinct_start;
    });
    if (distinct) best.push_back(u);
  }
  return best;
}

std::vector<LocalFit> RefineStarts(FitModel* model, const FitOptions& options,
                                   const std::vector<std::vector<double>>& starts) {
  // Continuation over the window length: the first stage ends shortly after the response starts,
  // where impact timing (gaps, bite time) dominates and the misfit has few local minima; each
  // stage doubles the fitted span and starts from the previous stage's answer.
  const std::vector<double> stages = ContinuationStages(*model, options);
  // The first timing_only_stages fit only the timing parameters; the others (dampings,
  // stiffness), which a short window hardly constrains, are held at their start there.
  std::vector<int> not_timing;
  for (int i = 0; i < model->parameters(); ++i) {
    if (!TimingParameter(model->free(i))) not_timing.push_back(i);
  }
  if (static_cast<int>(not_timing.size()) == model->parameters()) not_timing.clear();

  // The starts go through the stages side by side. A start that ends a stage where an earlier
  // one ended it (options.merge_distance) would go on along the same path: it stops there and
  // takes that start's continued fit.
  const int count = static_cast<int>(starts.size());
  std::vector<LocalFit> continued(count);
  std::vector<int> joined(count, -1);  // the start whose path this one joined
  for (int s = 0; s < count; ++s) continued[s].u = starts[s];
  std::vector<int> going(count);
  std::iota(going.begin(), going.end(), 0);
  for (size_t k = 0; k < stages.size() && !going.empty(); ++k) {
    const double divisor = stages[k];
    const bool timing_only = static_cast<int>(k) < options.timing_only_stages && divisor != 1.0;
    std::vector<LocalFit> fits = MapOverCopies<LocalFit>(
        *model, options.threads, static_cast<int>(going.size()), [&](FitModel& copy, int i) {
          copy.SetStage(divisor);
          return Refine(copy, options, continued[going[i]].u, divisor == 1.0,
                        options.stage_iterations, timing_only ? not_timing : std::vector<int>{});
        });
    std::vector<int> still;
    for (size_t i = 0; i < going.size(); ++i) {
      const int s = going[i];
      continued[s] = std::move(fits[i]);
      if (!continued[s].usable) continue;
      if (divisor != 1.0 && options.merge_distance > 0.0) {
        for (const int r : still) {
          if (SamePoint(continued[s].u, continued[r].u, options.merge_distance)) {
            joined[s] = r;
            break;
          }
        }
        if (joined[s] >= 0) continue;
      }
      still.push_back(s);
    }
    going = std::move(still);
  }
  for (int s = 0; s < count; ++s) {
    int root = s;
    while (joined[root] >= 0) root = joined[root];
    if (root != s) continued[s] = continued[root];
    continued[s].start = s;
  }

  // Each start gives its continued fit and, when it comes near, its direct one: the same start
  // refined on the whole window at once. A short stage sees the dampings poorly, and noise can
  // carry them into the basin of a neighbouring minimum of the whole window; a fit from a start
  // inside the right basin stays there. A capped try first: it is finished only when it comes
  // near the continued fit.
  const auto direct_fit = [&](FitModel& copy, int s) {
    std::vector<LocalFit> found;
    if (stages.size() <= 1) return found;
    copy.SetStage(1.0);
    // Either fit stops early where it comes back to the continued fit's minimum.
    const LocalFit* known = continued[s].usable ? &continued[s] : nullptr;
    LocalFit direct =
        Refine(copy, options, starts[s], false, options.direct_try_iterations, {}, known);
    const bool near =
        direct.usable && direct.cost < options.direct_retry_factor * continued[s].cost;
    if (near && !direct.rejoined) {
      direct = Refine(copy, options, direct.u, true, options.max_iterations, {}, known);
    }
    if (near) {
      direct.start = s;
      found.push_back(std::move(direct));
    }
    return found;
  };
  std::vector<LocalFit> minima;
  std::vector<std::vector<LocalFit>> directs =
      MapOverCopies<std::vector<LocalFit>>(*model, options.threads, count, direct_fit);
  for (int s = 0; s < count; ++s) {
    minima.push_back(std::move(continued[s]));
    for (auto& fit : directs[s]) minima.push_back(std::move(fit));
  }
  model->SetStage(1.0);
  return minima;
}

double PrecisionLength(const LocalFit& at, const std::vector<double>& u) {
  const auto n = static_cast<Eigen::Index>(at.u.size());
  if (at.precision.rows() != n || static_cast<Eigen::Index>(u.size()) != n) {
    return std::numeric_limits<double>::infinity();
  }
  Eigen::VectorXd d(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    d[i] = ParameterMap::AngleFromUnit(u[i]) - ParameterMap::AngleFromUnit(at.u[i]);
  }
  return std::sqrt(std::max(0.0, d.dot(at.precision * d)));
}

Search GlobalSearch(FitModel* model, const FitConfig& config, const FitOptions& options,
                    const std::vector<ChannelNoise>& noise, const std::vector<double>& start) {
  Search search;
  auto& minima = search.minima;
  const auto lowest = [&minima] {
    int best = -1;
    for (int k = 0; k < static_cast<int>(minima.size()); ++k) {
      if (minima[k].usable && (best < 0 || minima[k].cost < minima[best].cost)) best = k;
    }
    return best;
  };
  // The scan ranks its points on the first continuation stage, the short window after the onset
  // where impact timing decides; the best preselect_factor × starts go through that stage's fit.
  const auto search_from = [&](const FitConfig& settings, const std::vector<double>& from) {
    int points = 0;
    model->set_activity("scan of " + std::to_string(settings.scan_points) + " points");
    model->SetStage(ContinuationStages(*model, options).front());
    auto starts = ScanStarts(*model, settings, options, from,
                             settings.starts * options.preselect_factor, &points);
    model->set_activity("choosing " + std::to_string(settings.starts) + " starts");
    starts = PreselectStarts(model, options, starts, settings.starts);
    model->set_activity("refining " + std::to_string(starts.size()) + " starts");
    for (auto fit : RefineStarts(model, options, starts)) {
      fit.start += search.starts;
      minima.push_back(std::move(fit));
    }
    search.starts += static_cast<int>(starts.size());
    search.scan_points += points;
    search.best = lowest();
  };
  search_from(config, start);
  if (search.best < 0) return search;

  // A best minimum that leaves the residual unexplained is most often a wrong basin; so is one
  // that no more than half the starts reach, the others scattered over other valleys (a line
  // with many valleys, where the best found may be one more of them: random line 8708's wrong
  // valley took 2 of 4 starts). One more search, with a scan escalation_factor times as dense,
  // other points and twice the starts.
  const int fitted = static_cast<int>(model->FittedIndices().size());
  if (options.escalation_factor > 1 &&
      (2 * StartsAtBest(minima, search.best, search.starts) <= search.starts ||
       WorstResidualZ(*model, noise, minima[search.best].u, fitted) > options.misfit_z)) {
    FitConfig wider = config;
    wider.scan_points = config.scan_points * options.escalation_factor;
    wider.starts = config.starts * 2;
    wider.seed = config.seed + 1;
    search.escalated = true;
    search_from(wider, minima[search.best].u);
  }
  // Points near the best minimum, each refined with everything free; a refinement that comes
  // back to the best minimum stops there (the rejoin stop).
  const auto refine_beside_best = [&](const std::vector<std::vector<double>>& points) {
    for (auto& fit :
         MapOverCopies<LocalFit>(*model, options.threads, static_cast<int>(points.size()),
                                 [&](const FitModel&copy, int i) {
                                   return Refine(copy, options, points[i], true,
                                                 options.max_iterations, {}, &minima[search.best]);
                                 })) {
      fit.start = -1;
      minima.push_back(std::move(fit));
    }
    search.best = lowest();
  };
  // Basin hopping: a valley next door that every start missed.
  model->set_activity("basin hops");
  refine_beside_best(HopPoints(*model, minima[search.best].u, minima[search.best].cost, options));
  // Gap kicks: the neighbouring valleys of a wide gap's impact timing.
  model->set_activity("gap kicks");
  refine_beside_best(GapKicks(*model, minima[search.best].u, options));
  // A valley that bends sharply within a few standard errors: followed, a lower one along it.
  model->set_activity("following curved valleys");
  const std::vector<std::vector<double>> curved =
      CurvedValleyPoints(*model, minima[search.best].u, minima[search.best].cost, options,
                         &search.bound_walks, &search.gap_points);
  if (!curved.empty()) {
    LocalFit fit = Refine(*model, options, curved.front(), true, options.max_iterations);
    fit.start = -1;
    minima.push_back(std::move(fit));
    search.best = lowest();
  }
  // A coarse look along every parameter's axis from the best minimum; a probe below it is a
  // valley the starts missed: Levenberg–Marquardt goes on from there.
  model->set_activity("probing the best minimum");
  search.probes = ProfileProbes(*model, minima[search.best].u, options);
  for (int restart = 0; restart < options.profile_restarts; ++restart) {
    const ProfileProbe* lower = nullptr;
    for (const auto& probe : search.probes) {
      if (probe.cost < minima[search.best].cost - FloorCost(options) &&
          (lower == nullptr || probe.cost < lower->cost)) {
        lower = &probe;
      }
    }
    if (lower == nullptr ||
        !GoOnBelowBest(model, options, std::vector<double>(lower->u), &search)) {
      break;
    }
  }
  return search;
}

bool GoOnBelowBest(FitModel* model, const FitOptions& options, const std::vector<double>& u,
                   Search* search) {
  auto& minima = search->minima;
  LocalFit fit = Refine(*model, options, u, true, options.max_iterations);
  fit.start = -1;
  const bool lower = fit.usable && fit.cost < minima[search->best].cost;
  minima.push_back(std::move(fit));
  if (!lower) return false;
  search->best = static_cast<int>(minima.size()) - 1;
  search->probes = ProfileProbes(*model, minima[search->best].u, options);
  return true;
}

}  // namespace millkit::identify
