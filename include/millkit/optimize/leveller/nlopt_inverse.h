// NLopt inverse kinematics of the leveller linkage (SPEC.md §6.2): (Y1, Y2) → (β1, β2) within the
// working range, re-checked through the forward map and cross-checked against the closed form.
//
// Formulations (variables β in radians, bounds = working range):
//   kConstrained:  min |β − β0|²  s.t.  Y1(β) = Y1*, Y2(β) = Y2*   (LD_SLSQP; Newton-like on the
//                  two equality constraints, the objective only picks the solution nearest β0)
//   kLeastSquares: min (Y1(β) − Y1*)² + (Y2(β) − Y2*)²             (any bound-constrained
//   algorithm;
//                  stopval stops at (residual_tolerance/10)²)
// Start β0: the sine-linearised guess sin β ≈ J0⁻¹ (Y* − Y(0)) (J0 = ∂Y/∂β at β = 0), kept 10°
// inside the working range (away from the dead centres), or (0, 0).
// Stopping rules: xtol_abs on β, ftol_abs, maxeval (Options). Whatever NLopt reports (NLopt 2.7 can
// claim success at an infeasible point and throws roundoff_limited at good ones), the answer is
// accepted only if the forward map returns the target within residual_tolerance_mm and β lies in
// the working range; the Summary says which test decided. Objective/constraint wrappers are
// noexcept: the forward map does not throw, a failed assembly returns a large value / forced stop.
// Nearest reachable point: min |Y(β) − Y*|² over the working range (LD_SLSQP from a grid of
// starts), used to name the nearest reachable (Y1, Y2) when a target is out of reach.
#pragma once

#include <array>
#include <string>

#include "millkit/leveller/linkage.h"
#include "millkit/optimize/algorithm.h"

namespace millkit::leveller {

enum class InverseFormulation { kConstrained, kLeastSquares };

struct NloptInverseOptions {
  // kConstrained takes kLdSlsqp, kLnCobyla or kGnIsres; kLeastSquares any of them.
  optimize::Algorithm algorithm = optimize::Algorithm::kLdSlsqp;
  InverseFormulation formulation = InverseFormulation::kConstrained;
  bool linearised_start = true;         // false: start at β = (0, 0)
  double residual_tolerance_mm = 1e-9;  // acceptance test of the re-check
  double constraint_tolerance_mm = 1e-12;
  double xtol_abs_rad = 1e-14;
  double ftol_abs = 0.0;  // off by default; stopval/xtol decide
  int max_evaluations = 200;
  // Throws InputError naming the broken rule.
  void Validate() const;
};

struct NloptInverseSummary {
  std::string algorithm;
  std::string nlopt_result;  // NLopt's own verdict (or the exception it threw)
  bool accepted = false;     // our re-check: residual ≤ tolerance and β in range
  int evaluations = 0;
  double residual_mm = 0.0;
  double closed_form_difference_deg = 0.0;  // max |β_nlopt − β_closed|, NaN if no closed form
  double time_s = 0.0;
  std::string BriefReport() const;
};

struct NloptInverseResult {
  double beta1_deg = 0.0;
  double beta2_deg = 0.0;
  double y3_mm = 0.0;
  NloptInverseSummary summary;
};

class NloptInverse {
 public:
  // Throws InputError if the options are invalid.
  NloptInverse(const Linkage& linkage, const NloptInverseOptions& options);

  // Solves for one target. Non-convergence is reported in the summary (accepted = false).
  NloptInverseResult Solve(double y1_mm, double y2_mm) const;

  const NloptInverseOptions& options() const { return options_; }

 private:
  const Linkage* linkage_;
  NloptInverseOptions options_;
  Eigen::Vector2d y_at_zero_;
  Eigen::Matrix2d jacobian_at_zero_inverse_;  // rad per mm
};

struct ReachablePoint {
  double y1_mm = 0.0;
  double y2_mm = 0.0;
  double beta1_deg = 0.0;  // eccentric angles reaching it (NearestReachable)
  double beta2_deg = 0.0;
  double ah_mm = 0.0;  // cylinder lengths reaching it (NearestReachableByCylinders)
  double bg_mm = 0.0;
  double distance_mm = 0.0;  // infinity when no start assembled
};

// The reachable intermesh pair nearest to (y1, y2) (Euclidean in mm), over the eccentrics'
// working range.
ReachablePoint NearestReachable(const Linkage& linkage, double y1_mm, double y2_mm);
// The same for the hydraulic variant, over the cylinders' length ranges.
ReachablePoint NearestReachableByCylinders(const Linkage& linkage, double y1_mm, double y2_mm,
                                           const HydraulicRange& cylinders);

}  // namespace millkit::leveller
