// The step matrices of a linear ODE x' = A x in increment form:
//   S = exp(A τ),   Φ = ∫₀^τ exp(A s) ds = τ φ₁(A τ),   so that   x(t + τ) = x(t) + Φ x'(t),
//   x'(t + τ) = S x'(t).
// Stepping the increment keeps an equilibrium (A x = 0 in floating point) exactly where exp(Aτ) x
// would drift by roundoff, and rounds relative to the change rather than the state.
// Both come from one Taylor series of φ₁ (Paterson–Stockmeyer evaluation) at τ / 2^q with
// ‖A τ / 2^q‖₁ <= 1, then q doublings Φ(2τ) = Φ(τ) (I + S(τ)), S(2τ) = S(τ)² (Higham, Functions of
// Matrices, §10.3 and §10.7.4 for φ-functions).
#pragma once

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

#include "numerics/small_matvec.h"

namespace millkit::numerics {

// `extra_doublings` > 0 takes that many more halvings and doublings: the same matrices along
// another rounding path (their difference estimates the roundoff of both).
inline void ExpAndPhi1(const Eigen::MatrixXd& a, double tau, Eigen::MatrixXd* s,
                       Eigen::MatrixXd* phi, int extra_doublings = 0) {
  const int n = static_cast<int>(a.rows());
  const double theta = a.cwiseAbs().colwise().sum().maxCoeff() * std::abs(tau);
  int doublings = theta > 1.0 ? static_cast<int>(std::ceil(std::log2(theta))) : 0;
  doublings += extra_doublings;
  const double tau_b = std::ldexp(tau, -doublings);
  const double theta_b = std::ldexp(theta, -doublings);
  // Terms 0 … K of φ₁(B) = Σ B^k / (k+1)!: the tail after K is below θ^{K+1}/(K+2)! · e^θ.
  int terms = 1;
  double tail = theta_b / 2.0;
  while (terms < 30 && tail * std::exp(theta_b) > 0x1p-54) {
    ++terms;
    tail *= theta_b / (terms + 1);
  }
  const int degree = terms - 1;
  // Work space reused across calls (a solver builds a few dozen of these per run).
  thread_local std::vector<double> coefficient;
  thread_local std::vector<Eigen::MatrixXd> power;
  thread_local Eigen::MatrixXd phi1, product;
  coefficient.resize(degree + 1);
  double factorial = 1.0;  // (k+1)!
  for (int k = 0; k <= degree; ++k) {
    factorial *= (k + 1);
    coefficient[k] = 1.0 / factorial;
  }
  // Paterson–Stockmeyer: powers B¹ … B^p, then Horner in B^p over blocks of p coefficients.
  const int p = std::max(1, static_cast<int>(std::ceil(std::sqrt(static_cast<double>(terms)))));
  if (static_cast<int>(power.size()) < p + 1) power.resize(p + 1);
  power[1] = a * tau_b;
  for (int j = 2; j <= p; ++j) Multiply(power[j - 1], power[1], &power[j]);
  // Σ_j c_{ip+j} B^j for block i, added to *sum.
  auto add_block = [&](int i, Eigen::MatrixXd* sum) {
    sum->diagonal().array() += coefficient[static_cast<std::size_t>(i) * p];
    for (int j = 1; j < p && i * p + j <= degree; ++j) *sum += coefficient[i * p + j] * power[j];
  };
  const int blocks = degree / p;
  phi1.setZero(n, n);
  add_block(blocks, &phi1);
  for (int i = blocks - 1; i >= 0; --i) {
    Multiply(power[p], phi1, &product);
    phi1 = product;
    add_block(i, &phi1);
  }
  Multiply(power[1], phi1, s);
  s->diagonal().array() += 1.0;
  *phi = tau_b * phi1;
  for (int i = 0; i < doublings; ++i) {
    Multiply(*phi, *s, &product);
    *phi += product;
    Multiply(*s, *s, &product);
    *s = product;
  }
}

// c = a b in long double for the ladder's small matrices: each entry a dot product of a row of a
// (from a transposed copy, so both operands are contiguous) with a column of b, two rows at a
// time. Eigen's blocked product is not vectorised for long double and spends its time packing;
// this takes about 0.6 of its time at 9–24 rows. c must not alias a or b; at is work space.
using LongDoubleMatrix = Eigen::Matrix<long double, Eigen::Dynamic, Eigen::Dynamic>;
inline void MultiplyLongDouble(const LongDoubleMatrix& a, const LongDoubleMatrix& b,
                               LongDoubleMatrix* c, LongDoubleMatrix* at) {
  const Eigen::Index n = a.rows(), inner = a.cols(), cols = b.cols();
  *at = a.transpose();
  c->resize(n, cols);
  for (Eigen::Index j = 0; j < cols; ++j) {
    const long double* bj = b.col(j).data();
    Eigen::Index i = 0;
    for (; i + 1 < n; i += 2) {
      const long double* a0 = at->col(i).data();
      const long double* a1 = at->col(i + 1).data();
      long double s0 = 0.0L, s1 = 0.0L;
      for (Eigen::Index k = 0; k < inner; ++k) {
        s0 += a0[k] * bj[k];
        s1 += a1[k] * bj[k];
      }
      (*c)(i, j) = s0;
      (*c)(i + 1, j) = s1;
    }
    if (i < n) {
      const long double* a0 = at->col(i).data();
      long double s0 = 0.0L;
      for (Eigen::Index k = 0; k < inner; ++k) s0 += a0[k] * bj[k];
      (*c)(i, j) = s0;
    }
  }
}

// The same matrices over τ / 2^j for every level j = 0 … levels, for a stiff A (‖A τ‖ ≫ 1): the
// exact solver's propagator ladder. Computed in long double (64-bit mantissa) and rounded once to
// double: every doubling multiplies the error of the level below by about ‖S‖, and a stiff,
// non-normal A needs 30 or more of them, which in double left relative errors near 1e-7 in S
// (measured against a long double Padé reference on a coupling damped at d/J = 1e12).
inline void ExpAndPhi1Ladder(const Eigen::MatrixXd& a, double tau, int levels,
                             std::vector<Eigen::MatrixXd>* s, std::vector<Eigen::MatrixXd>* phi,
                             int extra_doublings = 0) {
  using Matrix = LongDoubleMatrix;
  const int n = static_cast<int>(a.rows());
  const Matrix al = a.cast<long double>();
  const long double theta = al.cwiseAbs().colwise().sum().maxCoeff() * std::abs(tau);
  // The finest level, halved further until ‖A τ_b‖₁ <= 1/2, where the series is summed.
  int below = 0;
  while (std::ldexp(theta, -(levels + below)) > 0.5L) ++below;
  below += extra_doublings;
  const long double tau_b = std::ldexp(static_cast<long double>(tau), -(levels + below));
  const Matrix b = al * tau_b;
  // φ₁(B) = Σ B^k / (k+1)!, terms until they fall below the long double epsilon (‖B‖ <= 1/2).
  Matrix phi1 = Matrix::Identity(n, n), term = Matrix::Identity(n, n), product, work;
  for (int k = 1; k < 40; ++k) {
    MultiplyLongDouble(term, b, &product, &work);
    term = product / static_cast<long double>(k + 1);
    phi1 += term;
    if (term.cwiseAbs().maxCoeff() < 1e-21L) break;
  }
  Matrix s_l;
  MultiplyLongDouble(b, phi1, &s_l, &work);
  s_l.diagonal().array() += 1.0L;
  Matrix phi_l = tau_b * phi1;
  s->resize(levels + 1);
  phi->resize(levels + 1);
  for (int j = levels + below; j >= 0; --j) {
    if (j <= levels) {
      (*s)[j] = s_l.cast<double>();
      (*phi)[j] = phi_l.cast<double>();
    }
    if (j == 0) break;
    MultiplyLongDouble(phi_l, s_l, &product, &work);
    phi_l += product;
    MultiplyLongDouble(s_l, s_l, &product, &work);
    s_l.swap(product);
  }
}

}  // namespace millkit::numerics
