// Roller support of the spindle shaft in the balancing device: the forces on the support rollers,
// the bending of a roller, the contact check of a roller on the shaft and the loads of the roller
// axle. Seed 002 §§1–4 (its figures 3–6 are not available), restated in SPEC.md §7. SI: N, m, Pa,
// N/m, N·m; angles in rad at this interface unless the name says deg.
//
// Each function checks its own preconditions and throws std::invalid_argument naming the
// parameter: they are the library's contract with its callers. User input is validated before it
// gets here (Validate() in balancer_input.h throws InputError naming the file key).
#pragma once

#include "millkit/balancer/balancer_input.h"

namespace millkit::balancer {

// β = arctan(lp / D), rad: the angle of the contact points of a roller pair seen from the shaft
// axis (seed 002 §1). Valid for lp > 0, D > 0.
double ExactSupportBetaRad(const SupportGeometry& geometry);

// β as the seed uses it: ExactSupportBetaRad rounded to the nearest multiple of
// beta_rounding_deg (no rounding when 0). Seed 002 prints arctan(190/600) = 17.5°; the exact angle
// is 17.571°, and the printed P1 follows only from 17.5° (see balancer_input.h).
double SupportBetaRad(const SupportGeometry& geometry);
// The same in degrees (rounding is done in degrees, where the step is stated).
double SupportBetaDeg(const SupportGeometry& geometry);

struct SupportReactions {
  double beta_exact_rad = 0.0;
  double beta_rad = 0.0;  // as used in P1, P2 and Pp
  double p1_N = 0.0;      // the larger reaction; the roller and its contact are checked with it
  double p2_N = 0.0;
};

// Reactions of the roller support under the load Q (seed 002 §1, SPEC.md §7):
//   P1 = Q / (4 cos(α + 2β)),   P2 = Q / (4 cos α).
// Requires Q >= 0, 0 <= α and α + 2β < 90° (so cos(α + 2β) > 0; checked in degrees, where
// 55° + 2 · 17.5° is exactly 90°); throws std::invalid_argument otherwise.
SupportReactions CalcSupportReactions(double support_load_N, const SupportGeometry& geometry);

struct RollerBending {
  double span_m = 0.0;     // 2a + 2b, between the roller's supports N1 and N2
  double q_N_per_m = 0.0;  // distributed load from the shaft over the length 2b
  double n1_N = 0.0;       // support reactions
  double n2_N = 0.0;
  double moment_at_load_start_Nm = 0.0;  // x1 = a (seed: section I–I, x1 = 84 mm)
  double moment_at_middle_Nm = 0.0;      // x2 = a + b (seed: section II–II, x2 = 329 mm), maximum
};

// The roller as a simply supported beam of span 2a + 2b with P1 spread over its middle 2b
// (seed 002 §2, fig. 4):
//   q = P1 / (2b),   N1 = N2 = P1 (a + b) / (2a + 2b)   (from ΣM_A = 0),
//   M(x) = N1 x                      for 0 <= x <= a,
//        = N1 x − q (x − a)² / 2     for a <= x <= a + 2b, mirrored beyond;
//   M(a) = N1 a,   M(a + b) = N1 (a + b) − q b² / 2 = P1 (2a + b) / 4, the maximum.
// Requires P1 >= 0, a >= 0, b > 0; throws std::invalid_argument otherwise.
RollerBending CalcRollerBending(double p1_N, const RollerBeam& beam);

// M(x) above, N·m, sagging positive; 0 outside [0, 2a + 2b] (beyond the beam's supports).
double RollerBendingMomentAt(double p1_N, const RollerBeam& beam, double x_m);

// Stress of a line contact of a steel roller on a steel shaft (seed 002 §3; Belyaev's formula for
// Poisson's ratio 0.3): σ = 0.418 sqrt(P E / (b r)), Pa, with P the force (N), E the reduced
// modulus (Pa), b the contact length (m), r the roller radius (m; the shaft's curvature is
// neglected, as in the seed). Requires P >= 0, E > 0, b > 0, r > 0.
double LineContactStressPa(double force_N, double modulus_Pa, double width_m, double radius_m);

struct ContactCheck {
  double roller_load_N = 0.0;  // Pр = (G + Q) / n
  double design_load_N = 0.0;  // Pв = k γ Pр
  double stress_Pa = 0.0;      // σсм
  double allowable_Pa = 0.0;   // [σсм]
  bool passes = false;         // σсм <= [σсм]
};

// Contact check of a roller (seed 002 §3): Pр = (G + Q) / n over the n rollers, Pв = k γ Pр,
// σсм = 0.418 sqrt(Pв E / (b r)) <= [σсм], r = d / 2. Requires G, Q >= 0 and the rules of
// RollerContact (balancer_input.h); throws std::invalid_argument otherwise.
ContactCheck CalcRollerContact(double support_load_N, double rod_weight_share_N,
                               const RollerContact& contact);

struct AxleLoads {
  double pp_N = 0.0;  // reaction of the support on the shaft through one roller pair
  double n3_N = 0.0;  // forces on the axle ends
  double n4_N = 0.0;
  double ra_N = 0.0;  // reactions of the axle supports
  double rb_N = 0.0;
  double moment_Nm = 0.0;  // bending moment at a support, the largest on the axle
};

// Axle of a roller pair (seed 002 §4, figs. 5 and 6): a beam on supports A and B a span b apart,
// loaded by N3 and N4 on overhangs a beyond A and beyond B:
//   Pp = Q / (2 cos(α + β)),   N3 = N4 = Pp / 2,
//   ΣM_A = 0: RB b − N4 (b + a) + N3 a = 0  →  RB = [N4 (b + a) − N3 a] / b,  RA = N3 + N4 − RB,
//   M = N3 a (constant between the supports when N3 = N4).
// The seed's printed Pp divides by 2 cos(α + β); its text "Q/2*cos(α+β)" drops the brackets.
// Requires Q >= 0, α + β < 90°, b > 0, a >= 0; throws std::invalid_argument otherwise.
AxleLoads CalcRollerAxle(double support_load_N, const SupportGeometry& geometry,
                         const RollerAxle& axle);

}  // namespace millkit::balancer
