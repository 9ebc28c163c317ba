// numerics/exp_phi.h: S = exp(Aτ) and Φ = ∫₀^τ exp(As) ds against Eigen's matrix exponential.
#include "numerics/exp_phi.h"

#include <catch2/catch.hpp>
#include <cmath>
#include <limits>
#include <random>
#include <unsupported/Eigen/MatrixFunctions>

using millkit::numerics::ExpAndPhi1;

namespace {
// Independent reference: exp of the block matrix [[A, I], [0, 0]] τ holds exp(Aτ) top left and
// Φ top right (Van Loan 1978). Padé there and the Taylor series here agree to roundoff.
void Reference(const Eigen::MatrixXd& a, double tau, Eigen::MatrixXd* s, Eigen::MatrixXd* phi) {
  const int n = static_cast<int>(a.rows());
  Eigen::MatrixXd block = Eigen::MatrixXd::Zero(2 * n, 2 * n);
  block.topLeftCorner(n, n) = a;
  block.topRightCorner(n, n).setIdentity();
  const Eigen::MatrixXd e = (block * tau).exp();
  *s = e.topLeftCorner(n, n);
  *phi = e.topRightCorner(n, n);
}

// A damped oscillator chain with a forcing block, like the drive line's scaled system matrix.
Eigen::MatrixXd Oscillators(int n, double frequency, std::mt19937* random) {
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(n, n);
  for (int i = 0; i + 1 < n; i += 2) {
    a(i, i + 1) = frequency;
    a(i + 1, i) = -frequency * (1.0 + 0.5 * uniform(*random));
    a(i + 1, i + 1) = -0.05 * frequency * std::abs(uniform(*random));
  }
  for (int i = 0; i < n; ++i) a(i, (i + 3) % n) += 0.1 * frequency * uniform(*random);
  return a;
}

double RelativeInf(const Eigen::MatrixXd& x, const Eigen::MatrixXd& reference) {
  return (x - reference).cwiseAbs().rowwise().sum().maxCoeff() /
         reference.cwiseAbs().rowwise().sum().maxCoeff();
}
}  // namespace

TEST_CASE("exp(Aτ) and τ φ1(Aτ) match the block-matrix exponential, with and without doublings",
          "[numerics]") {
  // ‖Aτ‖ from 0.01 (series only) to about 40 (six doublings); the error of both grows with the
  // doublings like the condition of exp itself, a few hundred ulps here.
  constexpr double kTolerance = 1e-13;
  std::mt19937 random(3);
  for (double scale : {0.01, 0.3, 1.0, 5.0, 40.0}) {
    const Eigen::MatrixXd a = Oscillators(15, 1000.0, &random);
    const double tau = scale / a.cwiseAbs().colwise().sum().maxCoeff();
    Eigen::MatrixXd s, phi, s_ref, phi_ref;
    Reference(a, tau, &s_ref, &phi_ref);
    for (int extra : {0, 1}) {
      ExpAndPhi1(a, tau, &s, &phi, extra);
      INFO("‖Aτ‖₁ = " << scale << ", extra doublings " << extra);
      CHECK(RelativeInf(s, s_ref) <= kTolerance);
      CHECK(RelativeInf(phi, phi_ref) <= kTolerance);
    }
  }
}

TEST_CASE("The ladder's long-double product matches Eigen's within the rounding of its sums",
          "[numerics]") {
  // Odd and even row counts (the product takes rows in pairs and one left over), a single entry,
  // and non-square shapes. Both sum the same products in long double in different orders, so
  // each entry may differ by the rounding of a sum of `inner` terms: inner · ε · Σ|a_ik b_kj|.
  using Matrix = Eigen::Matrix<long double, Eigen::Dynamic, Eigen::Dynamic>;
  const long double epsilon = std::numeric_limits<long double>::epsilon();
  std::mt19937 random(11);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  const int shapes[][3] = {{1, 1, 1}, {2, 3, 2}, {5, 5, 5}, {9, 7, 4}, {11, 11, 11}, {24, 24, 24}};
  for (const auto& shape : shapes) {
    Matrix a(shape[0], shape[1]), b(shape[1], shape[2]);
    for (Eigen::Index k = 0; k < a.size(); ++k) a.data()[k] = std::ldexp(uniform(random), k % 40);
    for (Eigen::Index k = 0; k < b.size(); ++k)
      b.data()[k] = std::ldexp(uniform(random), -(k % 30));
    Matrix c, work;
    millkit::numerics::MultiplyLongDouble(a, b, &c, &work);
    const Matrix reference = a * b;
    const Matrix bound = shape[1] * epsilon * (a.cwiseAbs() * b.cwiseAbs());
    INFO(shape[0] << " x " << shape[1] << " times " << shape[1] << " x " << shape[2]);
    REQUIRE(c.rows() == shape[0]);
    REQUIRE(c.cols() == shape[2]);
    CHECK(((c - reference).cwiseAbs().array() <= bound.array()).all());
    // Not a copy of the reference by accident: a changed entry of a moves a row of c.
    a(shape[0] - 1, 0) += 1.0L;
    millkit::numerics::MultiplyLongDouble(a, b, &c, &work);
    CHECK(c.row(shape[0] - 1) != reference.row(shape[0] - 1));
  }
}
