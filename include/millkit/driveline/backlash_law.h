// Backlash contact laws of a torsional link (SPEC.md §2.2). b is the TOTAL clearance, the dead
// zone is |ψ| <= b/2. With τc = c(ψ − b/2) for ψ > b/2, τc = c(ψ + b/2) for ψ < −b/2, τd = d ψ':
//  - limited (Modelica ElastoBacklash): ψ > b/2: m = 0 if τc + τd <= 0, else τc + min(τc, τd);
//    mirrored with max for ψ < −b/2. Continuous at first contact, never pulls.
//  - no_pull (Modelica ElastoBacklash2): m = max(τc + τd, 0) for ψ > b/2, mirrored.
//  - linear (seed 000, eq. 4): m = τc + τd outside the dead zone. Can pull.
// In the dead zone m = 0. With b = 0 every law is the plain spring-damper m = c ψ + d ψ'.
// Every law is piecewise linear in (ψ, ψ'): within one LinkMode, m = kψ ψ + kv ψ' + k0.
#pragma once

#include <algorithm>
#include <string>

namespace millkit::driveline {

enum class ContactLaw { kLimited, kNoPull, kLinear };

// Parses "limited" | "no_pull" | "linear"; returns false for anything else.
bool ParseContactLaw(const std::string& text, ContactLaw* law);
const char* ContactLawName(ContactLaw law);

// The linear piece of a law the link is on.
enum class LinkMode : unsigned char {
  kFree = 0,         // m = 0 (dead zone, or separating flank)
  kPosSpringDamper,  // m = c(ψ − b/2) + d ψ'
  kPosDoubleSpring,  // m = 2 c(ψ − b/2)   (limited, τd > τc)
  kNegSpringDamper,  // m = c(ψ + b/2) + d ψ'
  kNegDoubleSpring,  // m = 2 c(ψ + b/2)   (limited, τd < τc)
};

// Coefficients of m = kpsi ψ + kv ψ' + k0 in one mode.
struct LinkTorqueCoefficients {
  double kpsi = 0.0;
  double kv = 0.0;
  double k0 = 0.0;
};
LinkTorqueCoefficients CoefficientsOf(LinkMode mode, double c, double d, double b);

// The law evaluated directly (reference for tests and for the static analysis). Templated on the
// scalar so that derivative types (Ceres Jets) can pass through.
template <typename T>
T BacklashTorque(ContactLaw law, const T& c, const T& d, const T& b, const T& psi,
                 const T& psi_dot) {
  const T half = b * T(0.5);
  const T zero(0.0);
  if (psi > half) {
    const T tau_c = c * (psi - half);
    const T tau_d = d * psi_dot;
    switch (law) {
      case ContactLaw::kLinear:
        return tau_c + tau_d;
      case ContactLaw::kNoPull:
        return tau_c + tau_d > zero ? tau_c + tau_d : zero;
      case ContactLaw::kLimited:
        if (tau_c + tau_d <= zero) return zero;
        return tau_c + (tau_c < tau_d ? tau_c : tau_d);
    }
  }
  if (psi < -half) {
    const T tau_c = c * (psi + half);
    const T tau_d = d * psi_dot;
    switch (law) {
      case ContactLaw::kLinear:
        return tau_c + tau_d;
      case ContactLaw::kNoPull:
        return tau_c + tau_d < zero ? tau_c + tau_d : zero;
      case ContactLaw::kLimited:
        if (tau_c + tau_d >= zero) return zero;
        return tau_c + (tau_c > tau_d ? tau_c : tau_d);
    }
  }
  return zero;
}

}  // namespace millkit::driveline
