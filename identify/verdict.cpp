#include "identify/verdict.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "millkit/io/number_format.h"

namespace millkit::identify {

ResidualTest TestResidual(const std::vector<double>& residual, const ChannelNoise& noise,
                          double fitted_share) {
  ResidualTest test;
  const double n = static_cast<double>(residual.size());
  // The variance ratio's logarithm is ≈ normal with variance 2/ν_residual + 2/ν_noise.
  const double dof = std::max(1.0, n - fitted_share);
  const double sigma = noise.sigma_Nm;
  double rss = 0.0;
  for (const double r : residual) rss += r * r;
  test.variance_ratio =
      sigma > 0.0 ? rss / dof / (sigma * sigma) : std::numeric_limits<double>::infinity();
  test.variance_z =
      std::log(test.variance_ratio) / std::sqrt(2.0 / dof + 2.0 / std::max(1.0, noise.dof));
  // Whiteness: a wrong minimum leaves a smooth systematic residual, correlated over many lags,
  // long before it shows in the variance. Q = Σ_k (ρ_res(k) − ρ_noise(k))² / (1/n + 1/m) is
  // ≈ χ²(K) when the residual is the noise; Wilson–Hilferty turns it into a normal z.
  const auto& reference = noise.autocorrelation;
  const int lags = std::min<int>(static_cast<int>(reference.size()), static_cast<int>(n) / 4);
  if (lags >= 4) {
    const auto rho = Autocorrelation(residual, lags);
    const double variance = 1.0 / n + 1.0 / std::max(1, noise.quiet_samples);
    double q = 0.0;
    for (int k = 0; k < lags; ++k) q += (rho[k] - reference[k]) * (rho[k] - reference[k]);
    q /= variance;
    const double h = 2.0 / (9.0 * lags);
    test.whiteness_z = (std::cbrt(q / lags) - (1.0 - h)) / std::sqrt(h);
  }
  return test;
}

double WorstResidualZ(const FitModel& model, const std::vector<ChannelNoise>& noise,
                      const std::vector<double>& u, int fitted_quantities) {
  Eigen::VectorXd r;
  if (!model.ProjectedResiduals(u.data(), &r)) return std::numeric_limits<double>::infinity();
  double worst = 0.0;
  for (int b = 0; b < model.blocks(); ++b) {
    const auto& block = model.block(b);
    std::vector<double> residual(block.measured.size());
    for (size_t k = 0; k < residual.size(); ++k) residual[k] = r(block.offset + k) / block.weight;
    const ResidualTest test =
        TestResidual(residual, noise[b],
                     static_cast<double>(fitted_quantities) * residual.size() / model.residuals());
    worst = std::max({worst, test.variance_z, test.whiteness_z});
  }
  return worst;
}

void JudgeFit(const FitModel& model, const std::vector<ChannelNoise>& noise,
              const std::vector<LocalFit>& minima, int best, bool lower_found,
              const FitOptions& options, FitResult* result) {
  auto& summary = result->summary;
  auto& warnings = summary.warnings;
  const LocalFit& chosen = minima[best];
  bool misfit = false;
  bool ambiguous = false;

  const double total = std::max(1, summary.residuals);
  for (size_t b = 0; b < result->channels.size(); ++b) {
    auto& channel = result->channels[b];
    std::vector<double> residual(channel.fitted.size());
    for (size_t k = 0; k < residual.size(); ++k) {
      residual[k] = channel.fitted[k] - channel.measured[k];
    }
    const ResidualTest test =
        TestResidual(residual, noise[b], summary.fitted_quantities * channel.samples / total);
    channel.chi2_ratio = test.variance_ratio;
    channel.whiteness_z = test.whiteness_z;
    const double z = test.variance_z;
    const double z_white = test.whiteness_z;
    const double sigma = noise[b].sigma_Nm;
    if (z > options.misfit_z || z_white > options.misfit_z) {
      misfit = true;
      std::string name = channel.column;
      if (model.blocks() > static_cast<int>(model.block(model.blocks() - 1).channel) + 1) {
        name += "@" + channel.record_label;  // several records
      }
      warnings.push_back(
          "channel " + name + ": the residual (rms " + ShortNumber(channel.rms_residual) +
          " N*m) is " + ShortNumber(std::sqrt(channel.chi2_ratio)) + " times the record's noise (" +
          ShortNumber(sigma) + " N*m, " + channel.noise_source +
          "), beyond the level z = " + ShortNumber(options.misfit_z) +
          " (variance z = " + ShortNumber(z) + ", whiteness z = " + ShortNumber(z_white) +
          "): the model or the minimum does not explain the record");
    }
  }

  // Other minima as good within the noise but elsewhere.
  const double scale2 = summary.noise_scale * summary.noise_scale;
  for (size_t k = 0; k < minima.size(); ++k) {
    if (static_cast<int>(k) == best || !minima[k].usable) continue;
    const double delta_chi2 = 2.0 * (minima[k].cost - chosen.cost) / std::max(scale2, 1e-300);
    if (!(delta_chi2 < options.ambiguity_chi2)) continue;
    double farthest = 0.0;
    int which = -1;
    for (int s = 0; s < model.parameters(); ++s) {
      const auto& estimate = result->parameters[s];
      if (!estimate.identifiable || !(estimate.standard_error > 0.0)) continue;
      const double distance =
          std::abs(model.Physical(s, minima[k].u[s]) - estimate.value) / estimate.standard_error;
      if (distance > farthest) {
        farthest = distance;
        which = s;
      }
    }
    if (farthest > options.distinct_minimum_se) {
      ambiguous = true;
      const auto& estimate = result->parameters[which];
      warnings.push_back("another minimum fits as well (chi2 higher by " + ShortNumber(delta_chi2) +
                         ", below " + ShortNumber(options.ambiguity_chi2) + ") with " +
                         estimate.name + " = " +
                         ShortNumber(model.Physical(which, minima[k].u[which]), 6) + " " +
                         estimate.unit + ", " + ShortNumber(farthest) +
                         " standard errors from the best: the record does not decide between "
                         "them");
      break;
    }
  }

  // The best minimum reached only from a hop, a gap kick, a followed valley or a probe below a
  // minimum (start −1), well below every start's fit: the search's starts missed that valley, and
  // nothing says they did not miss a lower one. A start's fit within distinct_minimum_se of the
  // best under the best's linearisation (the Mahalanobis length: every direction, correlated ones
  // too) ended in the best's own valley, higher on a rough floor (the staircase of the no_pull
  // and linear laws): the starts did not miss it, and a warning says how rough it is.
  bool missed_by_starts = false;
  if (chosen.start < 0) {
    double best_start = std::numeric_limits<double>::infinity();
    double nearest = std::numeric_limits<double>::infinity();  // a start's fit, from the best
    for (const auto& fit : minima) {
      if (!fit.usable || fit.start < 0) continue;
      best_start = std::min(best_start, fit.cost);
      nearest = std::min(nearest, PrecisionLength(chosen, fit.u));
    }
    const double below = 2.0 * (best_start - chosen.cost) / std::max(scale2, 1e-300);
    if (below > options.ambiguity_chi2 && nearest <= options.distinct_minimum_se) {
      warnings.push_back(
          "the starts' fits stopped in the best minimum's valley (the nearest " +
          ShortNumber(nearest) + " standard errors from it), the lowest at a chi2 " +
          ShortNumber(below) +
          " above its bottom, which only a basin hop, a gap kick, a followed valley or a "
          "restart from a probe below a minimum reached: the misfit is rough there");
    } else if (below > options.ambiguity_chi2) {
      missed_by_starts = true;
      warnings.push_back(
          "the best minimum was reached only by a basin hop, a gap kick, a followed valley or a "
          "restart from a probe below a minimum, at a chi2 " +
          (std::isfinite(below) ? ShortNumber(below) + " below the best of the " +
                                      std::to_string(summary.starts) + " starts' fits"
                                : std::string("below every start's fit")) +
          ": the misfit has valleys the starts miss, and a lower one may remain (more starts "
          "or scan points, a narrower prior, or a longer record may settle it)");
    }
  }

  if (!chosen.converged) {
    warnings.insert(
        warnings.begin(),
        "Levenberg-Marquardt did not converge at the best minimum (" +
            std::string(ceres::TerminationTypeToString(chosen.summary.termination_type)) +
            " after " + std::to_string(chosen.summary.iterations.size()) +
            " iterations: " + chosen.summary.message + ")");
    summary.verdict = "not_converged";
  } else if (misfit) {
    summary.verdict = "misfit";
  } else if (ambiguous) {
    summary.verdict = "ambiguous";
  } else if (lower_found || missed_by_starts) {
    // Levenberg–Marquardt stopped, but a probe beside its answer is lower, or the starts missed
    // the best minimum's valley (the warnings say which): the search has not settled.
    summary.verdict = "not_converged";
  } else {
    summary.verdict = "ok";
  }
}

}  // namespace millkit::identify
