// Standard errors, correlations and identifiability of a fit (identify/ internal).
#pragma once

#include <Eigen/Dense>
#include <optional>
#include <vector>

#include "identify/fit_model.h"
#include "millkit/identify/fit.h"

namespace millkit::identify {

// Covariance over θ (scene parameters in unit coordinates, then gain and scaled offset of every
// block) from the weighted Jacobian: (JᵀJ)⁺ over the fitted columns by SVD, singular values
// below 1e-7 of the largest dropped, times noise_scale². A quantity the record hardly depends on
// (its column moves the residuals by less than 0.01 noise over its whole bound range) is held:
// it is left out of the others' covariance and gets only its own variance were every other one
// known, (noise_scale / ‖column‖)² (NaN for a constant column).
Eigen::MatrixXd Covariance(const Eigen::MatrixXd& jacobian, const std::vector<int>& fitted,
                           double noise_scale);

// Flags the parameters the record cannot determine (FitOptions: rank_tolerance,
// unidentifiable_fraction), on the column-scaled Jacobian (without the columns Covariance holds);
// sets reciprocal_condition.
//  - sensitivity: even if every other quantity were known, the standard error noise/‖column‖
//    would exceed the fraction of the bound width (the record hardly depends on it);
//  - collinearity: a singular value below rank_tolerance of the largest whose singular vector
//    involves the parameter (it trades off against others);
//  - its full standard error exceeds the fraction of the bound width.
void FlagUnidentifiable(const FitModel& model, const Eigen::MatrixXd& jacobian,
                        const std::vector<int>& fitted, double noise_scale,
                        const FitOptions& options, FitResult* result);

// The projected cost along each scene parameter's own axis (the others held) at
// options.profile_points unit coordinates spread evenly over its bounds ((k + ½)/points): a
// coarse global look at each parameter, which finds plateaus and lower valleys that the local
// linearisation cannot see.
struct ProfileProbe {
  int slot = 0;
  std::vector<double> u;
  double cost = 0.0;
};
std::vector<ProfileProbe> ProfileProbes(const FitModel& model, const std::vector<double>& u,
                                        const FitOptions& options);

// Basin hopping: options.hops points at options.hop_radius standard errors from the minimum u
// (cost `cost`) in random directions of the joint distribution of the scene parameters, the
// covariance from a fresh Jacobian. Levenberg–Marquardt from them finds a valley next door
// (rattling small gaps make them side by side) that the scan's starts all missed.
std::vector<std::vector<double>> HopPoints(const FitModel& model, const std::vector<double>& u,
                                           double cost, const FitOptions& options);

// Gap kicks: the minimum u with one fitted backlash set options.gap_kick wider, or narrower
// (relative), the others as they are; one point per gap and side that stays within the bounds.
std::vector<std::vector<double>> GapKicks(const FitModel& model, const std::vector<double>& u,
                                          const FitOptions& options);

// Curved valleys: where the cost ± profile_step standard errors along a parameter's straight
// profile direction rises more than FitOptions::curved_valley_ratio times the linearisation's
// prediction, the valley bends sharply within a few standard errors and the linearisation says
// nothing of what lies further along it. That parameter's profile is then followed: it is held
// at ± 2, 4, 8 … × profile_step up to profile_relax_reach standard errors from the minimum u
// (cost `cost`), the others refitted (curved_valley_iterations of Levenberg–Marquardt, on
// options.threads workers). Returns the held points whose χ² is more than 1 below the
// minimum's, lowest first: a lower valley along a curved one, which the starts and the hops
// missed. A parameter at a bound (within kAtBound in unit coordinates, or within
// FitOptions::bound_walk_se of its standard errors there) has its profile followed inward: held at
// 1/16, 1/8, 1/4 and 1/2 of its range from the bound, the others refitted the same way; those held
// fits go to `bound_walks` (slot, point, cost) as well. A gap the record hardly depends on (it
// never closes at u) is held just below the edge of its plateau, where it starts to close
// (FitOptions::open_gap_points), the others refitted the same way. Every fitted gap is held across
// its range, at (k + ½)/gap_profile_points in unit coordinates except within profile_step standard
// errors of u, the others refitted (profile_iterations each): a second valley behind a wall; these
// held fits go to `gap_points`.
std::vector<std::vector<double>> CurvedValleyPoints(const FitModel& model,
                                                    const std::vector<double>& u, double cost,
                                                    const FitOptions& options,
                                                    std::vector<ProfileProbe>* bound_walks,
                                                    std::vector<ProfileProbe>* gap_points);

// The profile check: for each scene parameter i, θ moves along its profile
// direction C e_i / √C_ii by ± profile_step (in standard errors); the linearisation predicts the
// cost to rise by ½ step² noise_scale². Where the actual projected cost rises less on either side,
// the standard error is widened by √(predicted/actual) (the cost is flatter than the Jacobian
// says: a weakly seen damping near a bound, an impact that appears or vanishes). Each probe is
// then relaxed by one Gauss–Newton step of the other quantities (`jacobian`, the full one at u;
// `fitted`, its fitted columns): where the valley curves away from the straight line, the
// relaxed probe lies lower, and that side of the profile is followed with the parameter held
// (FitOptions::profile_relax_widening; and where the straight probe rises past
// profile_bend_ratio times the prediction, since the valley then bends too sharply for a step
// with the minimum's Jacobian to say; a side that passes both is probed and relaxed again at
// twice profile_step, where a profile quadratic to the step may flatten: a shoulder); each
// point held at distance d with a profile χ² widens to d / √max(χ², 1). Every such point, and every
// point of `bound_walks` (CurvedValleyPoints), with a χ² below profile_chi2 widens every parameter
// p it moved by d_p to d_p / √max(χ², 1): in the quadratic picture the linearisation draws, no
// point at χ² lies further than √χ² standard errors in any parameter. Returns the widening factor
// per scene slot (1 where none), sets `lower` to the lowest point a probe found below the minimum's
// cost (the fit had not reached its minimum; empty when none did), and counts the followed sides in
// `relaxed_walks` when given.
std::vector<double> ProfileWidening(const FitModel& model, const std::vector<double>& u,
                                    const Eigen::MatrixXd& jacobian, const std::vector<int>& fitted,
                                    const Eigen::MatrixXd& covariance, double best_cost,
                                    double noise_scale, const FitOptions& options,
                                    const std::vector<ProfileProbe>& probes,
                                    const std::vector<ProfileProbe>& bound_walks,
                                    std::optional<ProfileProbe>* lower,
                                    int* relaxed_walks = nullptr);

// The widening the points held across a gap's range (CurvedValleyPoints' `gap_points`) imply:
// one within profile_chi2 of the best χ² that moved parameter j by d_j widens j's error to
// d_j / √max(χ², 1), the held gap's as well as the others'. Per scene slot, 1 where none. These
// points lie far outside the linearisation's reach: what they imply for each parameter is what
// they moved it by, not what its correlations at the minimum would carry (WidenAlongProfiles'
// `alone`).
std::vector<double> GapRangeWidening(const FitModel& model, const std::vector<double>& u,
                                     const Eigen::MatrixXd& covariance, double best_cost,
                                     double noise_scale, const FitOptions& options,
                                     const std::vector<ProfileProbe>& gap_points);

// Widens `covariance` (scene slots first, as Covariance) by ProfileWidening's factors. A
// profile flatter than the linearisation widens that parameter's spread by w; the others keep
// their spread given it (their regression on it and what is left), so whatever is correlated
// with it widens too: C += (w² − 1) c_i c_iᵀ / C_ii for every slot i with 1 < w < ∞, each term
// from the covariance as given. Its own variance becomes at least w² C_ii, and a quantity with
// correlation ρ to it gets C_jj (1 + (w² − 1) ρ²). Then each slot i with a factor a > 1 in
// `alone` has its variance raised to at least a² C_ii (the covariance as given), its row and
// column scaled: its correlations are kept and nothing is carried over to the others.
void WidenAlongProfiles(const std::vector<double>& widening, Eigen::MatrixXd* covariance,
                        const std::vector<double>& alone = {});

// Flags a parameter not identifiable where neighbouring axis probes have the same cost: the
// record does not change over that range (a gap that never closes there), so the local standard
// error describes only one side. A plateau more than 3 standard errors away, by
// `standard_errors` (per scene slot: the errors before the points held across a gap's range
// widened them, since those points lie on such plateaus themselves and say only what the plateau
// says), bounds it from one side only.
void FlagPlateaus(const FitModel& model, const std::vector<ProfileProbe>& probes,
                  const std::vector<double>& standard_errors, FitResult* result);

}  // namespace millkit::identify
