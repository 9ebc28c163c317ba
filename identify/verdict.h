// The verdict of a finished fit (identify/ internal; the rules are in
// include/millkit/identify/fit.h).
#pragma once

#include <vector>

#include "identify/fit_model.h"
#include "identify/multistart.h"
#include "identify/record_noise.h"
#include "millkit/identify/fit.h"

namespace millkit::identify {

// A channel's residual against the record's own noise (the misfit rules in
// include/millkit/identify/fit.h).
struct ResidualTest {
  double variance_ratio = 0.0;  // residual variance / noise variance
  double variance_z = 0.0;
  double whiteness_z = 0.0;  // 0 when the noise has no quiet stretch to compare with
};
// fitted_share: the channel's share of the fitted quantities (for the residual's dof).
ResidualTest TestResidual(const std::vector<double>& residual, const ChannelNoise& noise,
                          double fitted_share);
// The largest z of any block's tests at u (projected nuisance); +inf when u does not simulate.
double WorstResidualZ(const FitModel& model, const std::vector<ChannelNoise>& noise,
                      const std::vector<double>& u, int fitted_quantities);

// Sets result->summary.verdict and adds the reasons to its warnings. `noise` is per block;
// `best` indexes `minima`; result->parameters and channels are filled. lower_found: a probe
// beside the best minimum found a lower cost (not_converged unless a stronger verdict holds).
void JudgeFit(const FitModel& model, const std::vector<ChannelNoise>& noise,
              const std::vector<LocalFit>& minima, int best, bool lower_found,
              const FitOptions& options, FitResult* result);

}  // namespace millkit::identify
