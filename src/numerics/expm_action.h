// Action of the matrix exponential on a vector, y = exp(A τ) x, by the Taylor series with
// sub-steps (after Al-Mohy & Higham 2011, simplified): τ is split into s pieces with
// ‖A τ / s‖₁ <= 1 and on each the series is summed until a term no longer changes the sum
// (relative 2⁻⁵³, at most 60 terms). With ‖Aτ/s‖ <= 1 no term exceeds the sum by more than e, so
// the result is accurate to a few ulps of ‖y‖ times s. Cheaper than forming exp(Aτ) when only a
// few vectors are needed (event location).
#pragma once

#include <Eigen/Dense>
#include <cmath>

namespace millkit::numerics {

// `norm1` is ‖A‖₁ (passed in so callers can cache it). `work` avoids allocation.
inline void ExpmAction(const Eigen::MatrixXd& a, double norm1, double tau, Eigen::VectorXd* y,
                       Eigen::VectorXd* term, Eigen::VectorXd* next) {
  const double spread = norm1 * std::abs(tau);
  const int pieces = std::max(1, static_cast<int>(std::ceil(spread)));
  const double dt = tau / pieces;
  for (int p = 0; p < pieces; ++p) {
    *term = *y;
    for (int k = 1; k <= 60; ++k) {
      next->noalias() = a * *term;
      *term = *next * (dt / k);
      *y += *term;
      if (term->lpNorm<Eigen::Infinity>() <= 1.1e-16 * y->lpNorm<Eigen::Infinity>()) break;
    }
  }
}

}  // namespace millkit::numerics
