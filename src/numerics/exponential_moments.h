// The weights that carry a polynomial input through a first-order decay exactly:
//   y' = −a y + Σ_k u_k (σ/τ)^k over σ ∈ [0, τ]   gives   y(τ) = e^{−aτ} y(0) + τ Σ_k g_k(−aτ) u_k,
//   g_k(z) = ∫₀¹ e^{z(1−s)} s^k ds = k! φ_{k+1}(z).
// A fast recorder low-pass read by nothing else is carried this way beside a Taylor series of the
// slower rows, so that the series' pieces pay for the slower rows' rates only.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>

namespace millkit::numerics {

// g_0(z) … g_last(z) for z <= 0 into g[0 … last]. By parts, g_k = (k g_{k−1} − 1) / z: taken upward
// while k <= |z| (an error shrinks by k/|z| a step), and downward, g_{k−1} = (1 + z g_k) / k, above
// |z| (an error shrinks by |z|/k a step), from far enough past both that the start's error has
// died out below roundoff (the product of |z|/k over L steps past |z| is about e^{−L²/(2|z|)}).
inline void ExponentialMoments(double z, int last, double* g) {
  if (z == 0.0) {
    for (int k = 0; k <= last; ++k) g[k] = 1.0 / (k + 1);
    return;
  }
  const double magnitude = -z;
  const int upward = static_cast<int>(std::min<double>(std::floor(magnitude), last));
  g[0] = std::expm1(z) / z;
  for (int k = 1; k <= upward; ++k) g[k] = (k * g[k - 1] - 1.0) / z;
  if (upward >= last) return;
  const int top =
      std::max(last, upward) + 20 + static_cast<int>(std::ceil(std::sqrt(90.0 * magnitude)));
  // 1/k by table: the downward recurrence is a chain of dependent operations, and a division
  // costs several multiply-adds.
  static const std::array<double, 512> kInverse = [] {
    std::array<double, 512> inverse{};
    for (size_t k = 1; k < inverse.size(); ++k) inverse[k] = 1.0 / static_cast<double>(k);
    return inverse;
  }();
  double value = 1.0 / (top + 1 + magnitude);  // near g_top
  for (int k = top; k > upward + 1; --k) {
    const double inverse = k < static_cast<int>(kInverse.size()) ? kInverse[k] : 1.0 / k;
    value = (1.0 + z * value) * inverse;  // g_{k−1}
    if (k - 1 <= last) g[k - 1] = value;
  }
}

}  // namespace millkit::numerics
