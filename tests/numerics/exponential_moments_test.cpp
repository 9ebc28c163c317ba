// numerics/exponential_moments.h: g_k(z) = ∫₀¹ e^{z(1−s)} s^k ds against a series of positive
// terms, and the decay it stands for against a fine Taylor series.
#include "numerics/exponential_moments.h"

#include <catch2/catch.hpp>
#include <cmath>
#include <vector>

using millkit::numerics::ExponentialMoments;

namespace {
// For z <= 0, e^{z(1−s)} = e^z e^{|z| s}: g_k(z) = e^z Σ_i |z|^i / (i! (i + k + 1)), every term
// positive, summed in long double.
long double Reference(double z, int k) {
  const long double a = -static_cast<long double>(z);
  long double term = 1.0L, sum = 0.0L;  // term = |z|^i / i!
  for (int i = 0; i < 2000; ++i) {
    sum += term / (i + k + 1);
    term *= a / (i + 1);
    if (i > a && term < 1e-22L * sum) break;
  }
  return std::exp(-a) * sum;
}
}  // namespace

TEST_CASE("Exponential moments match a positive series from z = 0 to z = -200", "[numerics]") {
  constexpr int kLast = 60;
  std::vector<double> g(kLast + 1);
  for (const double z :
       {0.0, -1e-12, -1e-3, -0.25, -0.999, -1.0, -2.6, -7.5, -16.0, -49.9, -200.0}) {
    ExponentialMoments(z, kLast, g.data());
    for (int k = 0; k <= kLast; ++k) {
      const auto reference = static_cast<double>(Reference(z, k));
      INFO("z = " << z << ", k = " << k);
      CHECK(std::abs(g[k] - reference) <= 8e-16 * reference);
    }
  }
  // A shorter request gives the same leading weights.
  std::vector<double> few(4);
  ExponentialMoments(-7.5, 3, few.data());
  ExponentialMoments(-7.5, kLast, g.data());
  for (int k = 0; k <= 3; ++k) CHECK(std::abs(few[k] - g[k]) <= 4e-16 * g[k]);
}

TEST_CASE("Exponential moments carry a polynomial input through a decay exactly", "[numerics]") {
  // y' = −a y + u(σ), u = 3 − 2 (σ/τ) + 5 (σ/τ)², from y(0) = 1.5: the closed form against the
  // weights, with aτ from a fraction to many time constants.
  const std::vector<double> u{3.0, -2.0, 5.0};
  for (const double a_tau : {0.1, 2.6, 40.0}) {
    const double tau = 0.5e-3, a = a_tau / tau, y0 = 1.5;
    std::vector<double> g(u.size());
    ExponentialMoments(-a * tau, static_cast<int>(u.size()) - 1, g.data());
    double y = std::exp(-a * tau) * y0;
    for (size_t k = 0; k < u.size(); ++k) y += tau * g[k] * u[k];
    // Closed form: with s = σ/τ, y = e^{−aτ s}(y0 − P(0)) + P(s) for the polynomial particular
    // solution P, a P + P'/τ = u: P = p0 + p1 s + p2 s², a p2 = u2, a p1 + 2 p2/τ = u1,
    // a p0 + p1/τ = u0.
    const double p2 = u[2] / a, p1 = (u[1] - 2.0 * p2 / tau) / a, p0 = (u[0] - p1 / tau) / a;
    const double exact = std::exp(-a * tau) * (y0 - p0) + p0 + p1 + p2;
    INFO("a τ = " << a_tau);
    CHECK(std::abs(y - exact) <= 1e-14 * (std::abs(exact) + std::abs(y0)));
  }
}
