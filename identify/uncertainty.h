// Standard errors, correlations and identifiability of a fit (identify/ internal).
#pragma once

#include <vector>

#include <Eigen/Dense>

#include "identify/fit.h"
#include "identify/fit_model.h"

namespace millkit::identify {

// Covariance over θ (scene parameters in unit coordinates, then gain and scaled offset of every
// block) from the weighted Jacobian: (JᵀJ)⁺ over the fitted columns by SVD, singular values
// below 1e-7 of the largest dropped, times noise_scale². Constant columns get zero rows.
Eigen::MatrixXd Covariance(const Eigen::MatrixXd& jacobian, const std::vector<int>& fitted,
                           double noise_scale);

// Flags the parameters the record cannot determine (FitOptions: rank_tolerance,
// unidentifiable_fraction), on the column-scaled Jacobian; sets reciprocal_condition.
//  - sensitivity: even if every other quantity were known, the standard error noise/‖column‖
//    would exceed the fraction of the bound width (the record hardly depends on it);
//  - collinearity: a singular value below rank_tolerance of the largest whose singular vector
//    involves the parameter (it trades off against others);
//  - its full standard error exceeds the fraction of the bound width.
void FlagUnidentifiable(const FitModel& model, const Eigen::MatrixXd& jacobian,
                        const std::vector<int>& fitted, double noise_scale,
                        const FitOptions& options, FitResult* result);

// The profile check: for each identifiable scene parameter i, θ moves along its profile
// direction C e_i / √C_ii by ± profile_step (in standard errors); the linearisation predicts the
// cost to rise by ½ step² noise_scale². Where the actual projected cost rises less on either side,
// the standard error is widened by √(predicted/actual) (the cost is flatter than the Jacobian
// says: a weakly seen damping near a bound, an impact that appears or vanishes). Returns the
// widening factor per scene slot (1 where none), and sets `lower_found` when a probe found a cost
// below the minimum's (the fit had not reached its minimum).
std::vector<double> ProfileWidening(const FitModel& model, const std::vector<double>& u,
                                    const Eigen::MatrixXd& covariance, double best_cost,
                                    double noise_scale, const FitOptions& options,
                                    const std::vector<bool>& identifiable, bool* lower_found);

}  // namespace millkit::identify
