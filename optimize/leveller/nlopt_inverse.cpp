#include "millkit/optimize/leveller/nlopt_inverse.h"

#include <ceres/jet.h>

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

#include "millkit/io/input_error.h"
#include "millkit/io/number_format.h"
#include "optimize/nlopt_algorithm.h"

namespace millkit::leveller {
namespace {

constexpr double kRadToDeg = 180.0 / std::numbers::pi;
constexpr double kDegToRad = std::numbers::pi / 180.0;
// Residual returned when the linkage does not assemble (never inside a validated working range).
constexpr double kNoAssemblyResidualMm = 1e3;
// Starts per axis of the nearest-reachable search.
constexpr int kNearestStartsPerAxis = 5;
// The start stays this far inside the working range: at its ends the eccentrics sit at their
// dead centres, where ∂Y/∂β ≈ 0 and a gradient method started there does not move.
constexpr double kStartMarginRad = 10.0 * std::numbers::pi / 180.0;

using Jet = ceres::Jet<double, 2>;

struct Problem {
  const Linkage* linkage = nullptr;
  bool cylinders = false;  // x are the cylinder lengths |AH|, |BG| (mm), not angles (rad)
  double target[2] = {0.0, 0.0};
  double start[2] = {0.0, 0.0};
  int evaluations = 0;
  bool assembly_failed = false;
};

// Y(x) − target and its Jacobian (mm, mm/rad or mm/mm); false when the linkage does not assemble.
bool Residual(const Problem& p, const double* x, double r[2], double jac[4]) noexcept {
  Intermesh<Jet> y;
  if (p.cylinders) {
    if (!p.linkage->ForwardLengths(Jet(x[0], 0), Jet(x[1], 1), &y)) return false;
  } else if (!p.linkage->Forward(Jet(x[0], 0) * kRadToDeg, Jet(x[1], 1) * kRadToDeg, &y)) {
    return false;
  }
  r[0] = y.y1.a - p.target[0];
  r[1] = y.y2.a - p.target[1];
  if (jac != nullptr) {
    jac[0] = y.y1.v[0];
    jac[1] = y.y1.v[1];
    jac[2] = y.y2.v[0];
    jac[3] = y.y2.v[1];
  }
  return true;
}

double LeastSquaresObjective(unsigned /*n*/, const double* x, double* grad, void* data) noexcept {
  auto* p = static_cast<Problem*>(data);
  ++p->evaluations;
  double r[2];
  double j[4];
  if (!Residual(*p, x, r, j)) {
    p->assembly_failed = true;
    if (grad != nullptr) grad[0] = grad[1] = 0.0;
    return kNoAssemblyResidualMm * kNoAssemblyResidualMm;
  }
  if (grad != nullptr) {
    grad[0] = 2.0 * (r[0] * j[0] + r[1] * j[2]);
    grad[1] = 2.0 * (r[0] * j[1] + r[1] * j[3]);
  }
  return r[0] * r[0] + r[1] * r[1];
}

double DistanceObjective(unsigned /*n*/, const double* x, double* grad, void* data) noexcept {
  auto* p = static_cast<Problem*>(data);
  ++p->evaluations;
  const double d0 = x[0] - p->start[0];
  const double d1 = x[1] - p->start[1];
  if (grad != nullptr) {
    grad[0] = 2.0 * d0;
    grad[1] = 2.0 * d1;
  }
  return d0 * d0 + d1 * d1;
}

void TargetConstraint(unsigned /*m*/, double* result, unsigned /*n*/, const double* x, double* grad,
                      void* data) noexcept {
  auto* p = static_cast<Problem*>(data);
  double j[4];
  if (!Residual(*p, x, result, j)) {
    p->assembly_failed = true;
    result[0] = result[1] = kNoAssemblyResidualMm;
    if (grad != nullptr) std::fill(grad, grad + 4, 0.0);
    return;
  }
  if (grad != nullptr) std::copy(j, j + 4, grad);  // row-major m × n
}

std::string ResultName(nlopt::result r) {
  switch (r) {
    case nlopt::SUCCESS:
      return "SUCCESS";
    case nlopt::STOPVAL_REACHED:
      return "STOPVAL_REACHED";
    case nlopt::FTOL_REACHED:
      return "FTOL_REACHED";
    case nlopt::XTOL_REACHED:
      return "XTOL_REACHED";
    case nlopt::MAXEVAL_REACHED:
      return "MAXEVAL_REACHED";
    case nlopt::MAXTIME_REACHED:
      return "MAXTIME_REACHED";
    case nlopt::FAILURE:
      return "FAILURE";
    case nlopt::INVALID_ARGS:
      return "INVALID_ARGS";
    case nlopt::OUT_OF_MEMORY:
      return "OUT_OF_MEMORY";
    case nlopt::ROUNDOFF_LIMITED:
      return "ROUNDOFF_LIMITED";
    case nlopt::FORCED_STOP:
      return "FORCED_STOP";
    default:
      return "NLOPT_RESULT_" + std::to_string(static_cast<int>(r));
  }
}

// Runs opt.optimize and turns NLopt's exceptions into a verdict string; x keeps the last point.
std::string RunOptimizer(nlopt::opt& opt, std::vector<double>& x) {
  double f = 0.0;
  try {
    return ResultName(opt.optimize(x, f));
  } catch (const nlopt::roundoff_limited&) {
    return "ROUNDOFF_LIMITED (exception)";
  } catch (const nlopt::forced_stop&) {
    return "FORCED_STOP (exception)";
  } catch (const std::invalid_argument& e) {
    return std::string("INVALID_ARGS (exception: ") + e.what() + ")";
  } catch (const std::bad_alloc&) {
    return "OUT_OF_MEMORY (exception)";
  } catch (const std::runtime_error& e) {
    return std::string("FAILURE (exception: ") + e.what() + ")";
  }
}

}  // namespace

void NloptInverseOptions::Validate() const {
  if (!(residual_tolerance_mm > 0.0)) throw InputError("residual_tolerance_mm must be > 0");
  if (!(constraint_tolerance_mm > 0.0)) throw InputError("constraint_tolerance_mm must be > 0");
  if (!(xtol_abs_rad >= 0.0)) throw InputError("xtol_abs_rad must be >= 0");
  if (!(ftol_abs >= 0.0)) throw InputError("ftol_abs must be >= 0");
  if (max_evaluations < 1) throw InputError("max_evaluations must be >= 1");
  if (formulation == InverseFormulation::kConstrained &&
      !(algorithm == optimize::Algorithm::kLdSlsqp || algorithm == optimize::Algorithm::kLnCobyla ||
        algorithm == optimize::Algorithm::kGnIsres)) {
    throw InputError(std::string("algorithm ") +
                     nlopt::algorithm_name(optimize::ToNlopt(algorithm)) +
                     " does not take equality constraints; use the least-squares formulation");
  }
}

std::string NloptInverseSummary::BriefReport() const {
  return algorithm + ": " + (accepted ? "ACCEPTED" : "REJECTED") + " (NLopt: " + nlopt_result +
         "), " + std::to_string(evaluations) + " evaluations, residual " +
         FormatNumber(residual_mm) + " mm, |beta - closed form| " +
         FormatNumber(closed_form_difference_deg) + " deg, " + FormatNumber(time_s * 1e6) + " us";
}

NloptInverse::NloptInverse(const Linkage& linkage, const NloptInverseOptions& options)
    : linkage_(&linkage), options_(options) {
  options_.Validate();
  Intermesh<double> y0;
  const bool assembled = linkage.Forward(0.0, 0.0, &y0);
  y_at_zero_ = assembled ? Eigen::Vector2d(y0.y1, y0.y2) : Eigen::Vector2d::Zero();
  const Eigen::Matrix<double, 3, 2> j_deg = linkage.Jacobian(0.0, 0.0);
  jacobian_at_zero_inverse_ = (j_deg.topRows<2>() * kRadToDeg).inverse();
}

NloptInverseResult NloptInverse::Solve(double y1_mm, double y2_mm) const {
  const auto started = std::chrono::steady_clock::now();
  const auto& geo = linkage_->geometry();
  const double lo = geo.beta_min_deg * kDegToRad;
  const double hi = geo.beta_max_deg * kDegToRad;
  Problem problem;
  problem.linkage = linkage_;
  problem.target[0] = y1_mm;
  problem.target[1] = y2_mm;
  if (options_.linearised_start) {
    const Eigen::Vector2d s =
        jacobian_at_zero_inverse_ * (Eigen::Vector2d(y1_mm, y2_mm) - y_at_zero_);
    for (int i = 0; i < 2; ++i) {
      problem.start[i] = std::clamp(std::asin(std::clamp(s[i], -1.0, 1.0)),
                                    std::min(lo + kStartMarginRad, 0.5 * (lo + hi)),
                                    std::max(hi - kStartMarginRad, 0.5 * (lo + hi)));
    }
  }
  nlopt::opt opt(optimize::ToNlopt(options_.algorithm), 2);
  opt.set_lower_bounds({lo, lo});
  opt.set_upper_bounds({hi, hi});
  opt.set_xtol_abs(options_.xtol_abs_rad);
  if (options_.ftol_abs > 0.0) opt.set_ftol_abs(options_.ftol_abs);
  opt.set_maxeval(options_.max_evaluations);
  if (options_.formulation == InverseFormulation::kConstrained) {
    opt.set_min_objective(DistanceObjective, &problem);
    opt.add_equality_mconstraint(
        TargetConstraint, &problem,
        {options_.constraint_tolerance_mm, options_.constraint_tolerance_mm});
  } else {
    opt.set_min_objective(LeastSquaresObjective, &problem);
    const double stop = 0.1 * options_.residual_tolerance_mm;
    opt.set_stopval(stop * stop);
  }
  std::vector<double> x{problem.start[0], problem.start[1]};
  NloptInverseResult result;
  auto& summary = result.summary;
  summary.algorithm = nlopt::algorithm_name(optimize::ToNlopt(options_.algorithm));
  summary.nlopt_result = RunOptimizer(opt, x);
  summary.evaluations = problem.evaluations;

  // Our own verdict: forward re-check and range check.
  result.beta1_deg = x[0] * kRadToDeg;
  result.beta2_deg = x[1] * kRadToDeg;
  Intermesh<double> y;
  const bool in_range = x[0] >= lo && x[0] <= hi && x[1] >= lo && x[1] <= hi;
  if (linkage_->Forward(result.beta1_deg, result.beta2_deg, &y)) {
    result.y3_mm = y.y3;
    summary.residual_mm = std::max(std::abs(y.y1 - y1_mm), std::abs(y.y2 - y2_mm));
  } else {
    summary.residual_mm = std::numeric_limits<double>::infinity();
  }
  summary.accepted = in_range && summary.residual_mm <= options_.residual_tolerance_mm;
  const AngleSetpoint closed = linkage_->InverseClosedForm(y1_mm, y2_mm);
  summary.closed_form_difference_deg = closed.ok()
                                           ? std::max(std::abs(closed.beta1_deg - result.beta1_deg),
                                                      std::abs(closed.beta2_deg - result.beta2_deg))
                                           : std::numeric_limits<double>::quiet_NaN();
  summary.time_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  return result;
}

namespace {

// Least squares from a grid of starts over the box [lo, hi]², keeping the nearest assembled pair.
ReachablePoint NearestOverBox(const Linkage& linkage, double y1_mm, double y2_mm, bool cylinders,
                              const double lo[2], const double hi[2]) {
  ReachablePoint best;
  best.distance_mm = std::numeric_limits<double>::infinity();
  for (int i = 0; i < kNearestStartsPerAxis; ++i) {
    for (int k = 0; k < kNearestStartsPerAxis; ++k) {
      Problem problem;
      problem.linkage = &linkage;
      problem.cylinders = cylinders;
      problem.target[0] = y1_mm;
      problem.target[1] = y2_mm;
      nlopt::opt opt(nlopt::LD_SLSQP, 2);
      opt.set_lower_bounds({lo[0], lo[1]});
      opt.set_upper_bounds({hi[0], hi[1]});
      opt.set_xtol_abs(cylinders ? 1e-10 : 1e-13);
      opt.set_ftol_abs(1e-24);
      opt.set_maxeval(400);
      opt.set_min_objective(LeastSquaresObjective, &problem);
      std::vector<double> x{lo[0] + (hi[0] - lo[0]) * i / (kNearestStartsPerAxis - 1),
                            lo[1] + (hi[1] - lo[1]) * k / (kNearestStartsPerAxis - 1)};
      RunOptimizer(opt, x);
      x[0] = std::clamp(x[0], lo[0], hi[0]);
      x[1] = std::clamp(x[1], lo[1], hi[1]);
      Intermesh<double> y;
      const bool assembled = cylinders ? linkage.ForwardLengths(x[0], x[1], &y)
                                       : linkage.Forward(x[0] * kRadToDeg, x[1] * kRadToDeg, &y);
      if (!assembled) continue;
      const double distance = std::hypot(y.y1 - y1_mm, y.y2 - y2_mm);
      if (distance >= best.distance_mm) continue;
      best = ReachablePoint{};
      best.y1_mm = y.y1;
      best.y2_mm = y.y2;
      if (cylinders) {
        best.ah_mm = x[0];
        best.bg_mm = x[1];
      } else {
        best.beta1_deg = x[0] * kRadToDeg;
        best.beta2_deg = x[1] * kRadToDeg;
      }
      best.distance_mm = distance;
    }
  }
  return best;
}

}  // namespace

ReachablePoint NearestReachable(const Linkage& linkage, double y1_mm, double y2_mm) {
  const auto& geo = linkage.geometry();
  const double lo[2] = {geo.beta_min_deg * kDegToRad, geo.beta_min_deg * kDegToRad};
  const double hi[2] = {geo.beta_max_deg * kDegToRad, geo.beta_max_deg * kDegToRad};
  return NearestOverBox(linkage, y1_mm, y2_mm, false, lo, hi);
}

ReachablePoint NearestReachableByCylinders(const Linkage& linkage, double y1_mm, double y2_mm,
                                           const HydraulicRange& cylinders) {
  const double lo[2] = {cylinders.ah_min_mm, cylinders.bg_min_mm};
  const double hi[2] = {cylinders.ah_max_mm, cylinders.bg_max_mm};
  return NearestOverBox(linkage, y1_mm, y2_mm, true, lo, hi);
}

}  // namespace millkit::leveller
