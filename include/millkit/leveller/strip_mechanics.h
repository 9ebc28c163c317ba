// Strip mechanics for leveller setpoints (SPEC.md §6.1), elastic–perfectly-plastic rectangular
// section, written in ratios to the elastic limit:
//   κt = 2σs/(E h),  C = κ/κt (curvature ratio),  m = M/Mw (moment ratio)
//   skeleton (first loading):  m = C (|C| ≤ 1),  m = sign(C) (1.5 − 0.5/C²) (|C| ≥ 1);  |m| < 1.5
//   springback from (C, m): elastic unloading, residual curvature ratio C_res = C − m
//   reversed bending (Masing): from a turning point (C_r, m_r) the branch is
//     C = C_r + 2 g((m − m_r)/2), g = inverse skeleton, with memory: a branch that reaches the
//     turning point it started from rejoins the older branch (the skeleton after the first loop).
//   intermesh from curvature (small slopes, strip centreline): the strip passes lower roll 1,
//   upper roll 1#, lower roll 3, ... at x_i = (i − 1) t/2; with a = t/2 the second difference at
//   roll i is  D_i = y_i − (y_{i−1} + y_{i+1})/2 = −½ ∫_{−a}^{a} (a − |s|) κ(x_i + s) ds, hence
//     upper roll k (i = 2k):         ½ ∫ (a − |s|) κ ds = Y_k + h
//     lower roll between k, k + 1:  −½ ∫ (a − |s|) κ ds = (Y_k + Y_{k+1})/2 + h
//   (κ > 0 under the upper rolls, moment linear between the rolls, M1 = M7 = 0.)
//   roll collision: Y ≤ D − sqrt((D + h)² − (t/2)²)
// Setpoint: the entry target fixes the curvature at roll 2 (plastic depth ratio p: C2 = 1/(1 − p));
// the exit condition is either a flat strip (residual curvature 0 after roll 7, default) or a
// fixed curvature ratio at roll 6 (C6 = 1 is the seed's assumption M6 = Mw); the beam keeps the
// upper plunges collinear, Y3 = 2 Y2 − Y1. The moments M3…M5 (and M6 for a flat exit) solve the
// contact conditions at rolls 3, 4, 5 (Newton's method, forward-difference Jacobian); Y1 and Y3
// then follow from rolls 2 and 6.
// Work per unit length W = ∫ M dκ along the strip's history (exact on each Masing branch);
// straightening torque Mk = W D/2 (power = W v).
// Entry strip assumed flat and stress-free (κ0 = 0). Contact-point shift along the roll surface
// (second order in the slope) is neglected.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "millkit/leveller/leveller_config.h"
#include "millkit/leveller/roll_forces.h"

namespace millkit::leveller {

// Skeleton m(C), odd. Any finite C.
double MomentRatio(double curvature_ratio);
// Inverse skeleton C(m), odd; +/−infinity for |m| ≥ 1.5.
double CurvatureRatio(double moment_ratio);
// C − m(C): residual curvature ratio after elastic springback from the skeleton.
double ResidualCurvatureRatio(double curvature_ratio);
// Curvature ratio at which a fraction `plastic_ratio` ∈ [0, 1) of the thickness has yielded:
// C = 1/(1 − plastic_ratio).
double CurvatureRatioForPlasticDepth(double plastic_ratio);
// D − sqrt((D + h)² − (t/2)²), mm.
double CollisionLimitIntermesh_mm(double roll_diameter_mm, double thickness_mm, double pitch_mm);

// One strip section under a moment history, Masing with memory. Ratios as above.
class MasingSection {
 public:
  // Moves the moment monotonically from moment() to the ratio `target`; |target| < 1.5 and the
  // branch must stay finite (precondition, asserted). Accumulates the work ∫ m dC.
  void MoveTo(double target);
  double moment() const { return m_; }
  double curvature() const { return c_; }
  double work() const { return work_; }  // ∫ m dC, in units of Mw κt
  // Curvature at `moment_ratio` on the current branch without moving (memory rule applied).
  double CurvatureAt(double moment_ratio) const;

 private:
  struct Turn {
    double m;
    double c;
  };
  std::vector<Turn> turns_;  // reversal points, oldest first (empty: skeleton)
  double m_ = 0.0;
  double c_ = 0.0;
  int direction_ = 0;
  double work_ = 0.0;
};

// The strip through the seven rolls for given signed moment ratios m_i (m1 = m7 = 0, positive
// under the upper rolls).
struct StripPass {
  std::array<double, 7> second_difference_mm{};  // D_i (index i−1), zero at rolls 1 and 7
  std::array<double, 7> curvature_ratio{};       // C at each roll
  double work_per_length_N = 0.0;                // W = ∫ M dκ, J/m
  double exit_residual_curvature_ratio = 0.0;
};

// Samples per roll spacing for the curvature integrals (Simpson; even).
inline constexpr int kStripSamplesPerSpan = 400;

StripPass SimulateStripPass(const Strip& strip, double pitch_mm,
                            const std::array<double, 7>& moment_ratio,
                            int samples_per_span = kStripSamplesPerSpan);

enum class ExitCondition { kFlat, kFixedCurvature };

struct SetpointOptions {
  double entry_plastic_ratio = 0.6;  // fraction of h yielded at roll 2, [0, 1)
  ExitCondition exit = ExitCondition::kFlat;
  double exit_curvature_ratio = 1.0;  // kFixedCurvature: C at roll 6, (0, C_entry]
  double tolerance_mm = 1e-10;        // Newton stop: max contact residual
  int max_iterations = 60;
  // Throws InputError naming the field and the rule.
  void Validate() const;
};

struct SetpointSummary {
  bool converged = false;
  int iterations = 0;
  double residual_mm = 0.0;
  std::string message;
  std::string BriefReport() const;
};

struct StripSetpoint {
  std::array<double, 3> intermesh_mm{};  // Y1, Y2, Y3
  std::array<double, 7> moment_ratio{};  // signed m_i
  RollMoments moments_Nm{};              // magnitudes
  RollForces forces_kN{};
  double total_force_kN = 0.0;
  double straightening_torque_kNm = 0.0;  // Mk = W D/2
  double power_kW = 0.0;
  double exit_residual_curvature_ratio = 0.0;
  double collision_limit_mm = 0.0;
  SetpointSummary summary;
};

// Entry/exit intermesh, forces, torque and power for one strip (seed assumptions above).
// Throws InputError for an invalid strip or options; non-convergence is in the summary.
StripSetpoint ComputeStripSetpoint(const Strip& strip, const MachineData& machine,
                                   const SetpointOptions& options);

}  // namespace millkit::leveller
