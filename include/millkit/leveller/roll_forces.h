// Roll forces, straightening torque and drive power of the seven-roll leveller (SPEC.md §6.1,
// seed 004 §1).
//
//   Mw = σs b h² / 6           elastic-limit moment of the rectangular strip section (N·m)
//   Ms = e Mw, e = 1.5         fully plastic moment (shape factor of a rectangle)
//   P_i = 2 (M_{i−1} + 2 M_i + M_{i+1}) / t,  M_1 = M_7 = 0,  ΣP = 8 ΣM / t
//     (t = pitch between rolls of the same row; adjacent rolls are t/2 apart; moments are the
//      magnitudes at the rolls, they alternate in sign along the strip)
//   seed moment profile: M2 = M3 = M4 = Ms, M5 = (Ms + Mw)/2, M6 = Mw
//   N = [Mk + ΣP (f + μ d/2)] · 2v / (D η)     drive power (W with SI inputs)
//
// The seed's table (P1..P7 = 94.05, 282.15, 376.2, 346.475, 257.32, 133.525, 34.6 kN) follows from
// the profile only with Mw = 3460 N·m (= Ms/2.718, e replaced by Euler's number), not with the
// stated Mw = Ms/1.5 = 6270 N·m. The toolkit computes the stated physics by default and the seed's
// table when Mw is given explicitly. Even then the seed's P5 = 257.32 kN is 0.02 kN above
// 2(Ms + 2M5 + M6)/t = 257.30 kN (no Mw gives P4, P5, P6, P7 at once); its ΣP = 1524.32 kN is the
// sum of the printed column, 8ΣM/t = 1524.30 kN.
//
// Straightening torque, seed reading (the seed's formula is lost in extraction; seed assumptions:
// every bending moment is Ms, springback dissipates nothing):
//   Mk = Ms (D/2) [κ0 + (n − 3) κt],  κt = 2σs/(E h)
// i.e. each of the n − 3 = 4 reversals between the loaded rolls 2…6 drives κt of plastic
// curvature at Ms, plus the strip's average original curvature κ0 at roll 2. With E = 2.1e5 MPa,
// κ0 = 0, f = 0.2 mm, μ = 0.005, η = 0.85 it gives Mk = 2.956 kN·m and N = 98.7 kW against the
// seed's 99.3 kW (−0.6 %); 99.3 kW needs κ0 = 0.0255 1/m, which the seed does not print.
// The strip-mechanics model (strip_mechanics.h) computes Mk from the Masing work instead.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

#include "millkit/leveller/leveller_config.h"

namespace millkit::leveller {

// A strip grade and size. Units: MPa, mm. Valid: all > 0.
struct Strip {
  double yield_MPa = 550.0;   // σs
  double youngs_MPa = 2.1e5;  // E
  double thickness_mm = 6.0;  // h
  double width_mm = 1900.0;   // b
};

// A field of a Strip that breaks its rule.
struct StripDefect {
  std::string field;  // yield_mpa, youngs_mpa, thickness_mm or width_mm
  std::string rule;   // "must be > 0 (got x)"
};

// Every field that is not finite and > 0, in the order yield_mpa, youngs_mpa, thickness_mm,
// width_mm (a command line names its own flag for the field).
std::vector<StripDefect> FindStripDefects(const Strip& strip);

// Throws InputError "<where>: <field> must be > 0 (got x)" for the first of FindStripDefects.
void ValidateStrip(const Strip& strip, const std::string& where);

// Mw = σs b h²/6, N·m.
double ElasticLimitMoment_Nm(const Strip& strip);
// κt = 2σs/(E h), 1/m.
double ElasticLimitCurvature_per_m(const Strip& strip);

// Bending moment magnitudes at rolls 1..7, N·m (M1 = M7 = 0).
using RollMoments = std::array<double, 7>;
using RollForces = std::array<double, 7>;

// Seed assumptions (SPEC.md §6.1).
RollMoments SeedMomentProfile(double ms_Nm, double mw_Nm);

// P_i = 2 (M_{i−1} + 2 M_i + M_{i+1}) / t, kN, for a pitch t in mm. Precondition: M1 = M7 = 0.
RollForces RollForcesFromMoments_kN(const RollMoments& moments_Nm, double pitch_mm);

double Sum(const RollForces& forces);

// ΣP (f + μ d/2), kN·m.
double FrictionTorque_kNm(double total_force_kN, const MachineData& machine);

// N = [Mk + ΣP (f + μ d/2)] · 2v / (D η), kW.
double DrivePower_kW(double straightening_torque_kNm, double total_force_kN,
                     const MachineData& machine);

// Seed reading of the straightening torque (see the file comment), kN·m.
// κ0 = average original curvature (1/m, ≥ 0); roll_count = n.
double SeedStraighteningTorque_kNm(double ms_Nm, double kappa_t_per_m, double kappa0_per_m,
                                   int roll_count, double roll_diameter_mm);

// The `forces` calculation: the seed's method for one strip on one machine.
struct ForcesOptions {
  double shape_factor = 1.5;              // e, Ms = e · σs b h²/6
  std::optional<double> mw_override_Nm;   // Mw given explicitly (the seed's 3460 N·m)
  double original_curvature_per_m = 0.0;  // κ0
  // Throws InputError naming the option and the rule.
  void Validate() const;
};

struct ForcesReport {
  double mw_Nm = 0.0;
  double ms_Nm = 0.0;
  double kappa_t_per_m = 0.0;
  RollMoments moments_Nm{};
  RollForces forces_kN{};
  double total_force_kN = 0.0;
  double straightening_torque_kNm = 0.0;
  double friction_torque_kNm = 0.0;
  double power_kW = 0.0;
  std::vector<std::string> warnings;  // machine limits exceeded
  bool mw_given = false;              // Mw was given (ForcesOptions::mw_override_Nm)
};

ForcesReport ComputeForces(const Strip& strip, const MachineData& machine,
                           const ForcesOptions& options);

// Machine-limit checks shared by `forces` and `table`: roll force, total force, motor power.
std::vector<std::string> CheckMachineLimits(const RollForces& forces_kN, double power_kW,
                                            const MachineData& machine);

}  // namespace millkit::leveller
