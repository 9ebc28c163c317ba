// Backlash contact laws of a torsional link (SPEC.md §2.2): the one home of the law. b is the TOTAL
// clearance, the dead zone is |ψ| <= b/2. With τc = c(ψ − b/2) for ψ > b/2, τc = c(ψ + b/2) for
// ψ < −b/2, τd = d ψ':
//  - limited (Modelica ElastoBacklash): ψ > b/2: m = 0 if τc + τd <= 0, else τc + min(τc, τd);
//    mirrored with max for ψ < −b/2. Continuous at first contact, never pulls.
//  - no_pull (Modelica ElastoBacklash2): m = max(τc + τd, 0) for ψ > b/2, mirrored.
//  - linear (seed 000, eq. 4): m = τc + τd outside the dead zone. Can pull.
// In the dead zone m = 0. A link with b = 0 has no law: the model runs it as the plain
// spring-damper m = c ψ + d ψ'.
//
// Every law is piecewise linear in (ψ, ψ'). This unit owns, per law:
//  - the regions (LinkPhase) and the linear piece each is on (ModeOf, LinkMode);
//  - the torque coefficients of each piece, m = kψ ψ + kv ψ' + k0 (CoefficientsOf);
//  - the switching surfaces of one link as rows over (ψ, ψ', 1) (LinkSurfaceRows) and the side
//    each takes when it cannot be told (kLinkDefaultSides);
//  - the region from the sides of the surfaces, with its tie-breaks (PhaseFromSides);
//  - the surfaces each region watches, and on which side (WatchedSurfaces).
// The Model assembles its tables from these per-link answers; BacklashTorque, the law evaluated
// directly, is tested against them.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

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

// Where a backlash link is: region (dead zone, positive or negative flank) and the linear piece of
// its law. Free phases carry m = 0.
enum class LinkPhase : std::uint8_t {
  kDead,
  kPosFree,
  kPosSpringDamper,
  kPosDoubleSpring,
  kNegFree,
  kNegSpringDamper,
  kNegDoubleSpring,
};

// The regions a law has: linear {dead, ±sd}; no_pull adds ±free; limited adds ±2c.
std::vector<LinkPhase> RegionsOf(ContactLaw law);
// Short name of a region: "dead", "+free", "+sd", "+2c", "-free", "-sd", "-2c".
const char* LinkPhaseName(LinkPhase phase);
// The linear piece a region is on (kFree for the dead zone and the free flanks).
LinkMode ModeOf(LinkPhase phase);

// Coefficients of m = kpsi ψ + kv ψ' + k0 in one mode.
struct LinkTorqueCoefficients {
  double kpsi = 0.0;
  double kv = 0.0;
  double k0 = 0.0;
};
LinkTorqueCoefficients CoefficientsOf(LinkMode mode, double c, double d, double b);
// The same for a region: CoefficientsOf(ModeOf(phase), c, d, b).
LinkTorqueCoefficients CoefficientsOf(LinkPhase phase, double c, double d, double b);
// The largest kψ over the regions of `law` (2c for limited, else c): the stiffest piece.
double StiffestPieceStiffness(ContactLaw law, double c);

// Switching surfaces of one backlash link, with τc± = c(ψ ∓ b/2):
//   S0 = ψ − b/2, S1 = ψ + b/2, S2 = τc+ + d ψ', S3 = d ψ' − τc+, S4 = τc− + d ψ', S5 = d ψ' − τc−.
// Every law has the six (linear watches S0 and S1 only).
inline constexpr int kLinkSurfaceCount = 6;
enum LinkSurface : int { kS0 = 0, kS1, kS2, kS3, kS4, kS5 };
// A surface is affine in (ψ, ψ') like a torque piece: g = kpsi ψ + kv ψ' + k0.
using LinkSurfaceRow = LinkTorqueCoefficients;
std::array<LinkSurfaceRow, kLinkSurfaceCount> LinkSurfaceRows(double c, double d, double b);
// The side of each surface when it cannot be told (on it to roundoff and no motion off it): the
// side without contact, or the spring-damper piece. With these sides on a surface the region is
// the one BacklashTorque takes there.
inline constexpr std::array<int, kLinkSurfaceCount> kLinkDefaultSides = {-1, 1, -1, -1, 1, 1};
// Whether a surface found on it to roundoff at an event takes its side from the motion before the
// event (its first moving derivative), or its default side. S3 and S5 (τd = τc, where limited
// changes from the spring-damper piece to the double spring) take the default, the spring-damper
// piece: S3 is on it to roundoff away from an event on S3 itself only at the corner ψ = b/2,
// ψ' = 0, where every piece's torque is zero and the motion before (free, or the dead zone)
// shows τd > τc for any push. There the double spring, without the damper, pushes a light mass
// back across S2 within picoseconds and the free flank pushes it forward again (a chatter, found
// by the driveline fuzzer); the spring-damper piece holds it at the torque that carries it, and
// a real push leaves it across S3 at the next event. At an event of another link, a link on the
// double spring at that corner keeps it (Model::Classify's `before`).
inline constexpr std::array<bool, kLinkSurfaceCount> kLinkSideFromMotion = {true,  true, true,
                                                                            false, true, false};

// The region under `law` from the sides (+1 or −1) of the link's six surfaces, side[kS0..kS5].
// Tie-breaks: contact needs S0 > 0 (S1 < 0); limited frees on S2 <= 0 (S4 >= 0) and takes the
// spring-damper piece on S3 < 0 (S5 > 0), the double spring otherwise, as BacklashTorque does.
LinkPhase PhaseFromSides(ContactLaw law, const int* side);

// The surfaces whose crossing changes the region (the others need not be watched), each with the
// side (+1 or −1) the region is on. At most three per region.
struct LinkSurfaceSide {
  int surface;
  int side;
};
struct WatchedLinkSurfaces {
  std::array<LinkSurfaceSide, 3> list{};
  int count = 0;
  const LinkSurfaceSide* begin() const { return list.data(); }
  const LinkSurfaceSide* end() const { return list.data() + count; }
};
WatchedLinkSurfaces WatchedSurfaces(ContactLaw law, LinkPhase phase);

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
