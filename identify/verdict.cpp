#include "identify/verdict.h"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>

namespace millkit::identify {
namespace {

std::string Short(double value, int digits = 3) {
  std::ostringstream out;
  out << std::setprecision(digits) << value;
  return out.str();
}

}  // namespace

void JudgeFit(const FitModel& model, const std::vector<ChannelNoise>& noise,
              const std::vector<LocalFit>& minima, int best, const FitOptions& options,
              FitResult* result) {
  auto& summary = result->summary;
  auto& warnings = summary.warnings;
  const LocalFit& chosen = minima[best];
  bool misfit = false;
  bool ambiguous = false;

  // The residual against the record's own noise, channel by channel: the variance ratio's
  // logarithm is ≈ normal with variance 2/ν_residual + 2/ν_noise.
  const double total = std::max(1, summary.residuals);
  for (size_t b = 0; b < result->channels.size(); ++b) {
    auto& channel = result->channels[b];
    const double n = channel.samples;
    const double fitted_share = summary.fitted_quantities * n / total;
    const double dof = std::max(1.0, n - fitted_share);
    const double sigma = noise[b].sigma_Nm;
    const double rss = channel.rms_residual * channel.rms_residual * n;
    channel.chi2_ratio =
        sigma > 0.0 ? rss / dof / (sigma * sigma) : std::numeric_limits<double>::infinity();
    const double spread = std::sqrt(2.0 / dof + 2.0 / std::max(1.0, noise[b].dof));
    const double z = std::log(channel.chi2_ratio) / spread;
    // Whiteness: a wrong minimum leaves a smooth systematic residual, correlated over many lags,
    // long before it shows in the variance. Q = Σ_k (ρ_res(k) − ρ_noise(k))² / (1/n + 1/m) is
    // ≈ χ²(K) when the residual is the noise; Wilson–Hilferty turns it into a normal z.
    const auto& reference = noise[b].autocorrelation;
    const int lags = std::min<int>(static_cast<int>(reference.size()), channel.samples / 4);
    double z_white = 0.0;
    if (lags >= 4) {
      std::vector<double> residual(channel.fitted.size());
      for (size_t k = 0; k < residual.size(); ++k)
        residual[k] = channel.fitted[k] - channel.measured[k];
      const auto rho = Autocorrelation(residual, lags);
      const double variance = 1.0 / n + 1.0 / std::max(1, noise[b].quiet_samples);
      double q = 0.0;
      for (int k = 0; k < lags; ++k) q += (rho[k] - reference[k]) * (rho[k] - reference[k]);
      q /= variance;
      const double h = 2.0 / (9.0 * lags);
      channel.whiteness_z = (std::cbrt(q / lags) - (1.0 - h)) / std::sqrt(h);
      z_white = channel.whiteness_z;
    }
    if (z > options.misfit_z || z_white > options.misfit_z) {
      misfit = true;
      std::string name = channel.column;
      if (model.blocks() > static_cast<int>(model.block(model.blocks() - 1).channel) + 1) {
        name += "@" + channel.record_label;  // several records
      }
      warnings.push_back(
          "channel " + name + ": the residual (rms " + Short(channel.rms_residual) + " N*m) is " +
          Short(std::sqrt(channel.chi2_ratio)) + " times the record's noise (" + Short(sigma) +
          " N*m, " + channel.noise_source + "), beyond the level z = " + Short(options.misfit_z) +
          " (variance z = " + Short(z) + ", whiteness z = " + Short(z_white) +
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
      warnings.push_back("another minimum fits as well (chi2 higher by " + Short(delta_chi2) +
                         ", below " + Short(options.ambiguity_chi2) + ") with " + estimate.name +
                         " = " + Short(model.Physical(which, minima[k].u[which]), 6) + " " +
                         estimate.unit + ", " + Short(farthest) +
                         " standard errors from the best: the record does not decide between "
                         "them");
      break;
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
  } else {
    summary.verdict = "ok";
  }
}

}  // namespace millkit::identify
