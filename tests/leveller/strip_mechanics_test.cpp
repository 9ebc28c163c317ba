// Strip mechanics (SPEC.md §6.1): moment-curvature law, Masing reversals, intermesh from curvature,
// setpoints.
#include "millkit/leveller/strip_mechanics.h"

#include <catch2/catch.hpp>
#include <cmath>

using namespace millkit::leveller;
using Catch::Matchers::WithinAbs;
using Catch::Matchers::WithinRel;

namespace {

constexpr double kRoundoff = 1e-12;
// Simpson integration of a C¹ curvature field with kStripSamplesPerSpan samples.
constexpr double kQuadratureRel = 1e-8;

Strip ThinStrip() { return Strip{550.0, 2.1e5, 3.0, 1250.0}; }

}  // namespace

TEST_CASE("The moment-curvature law is linear to the elastic limit and tends to 1.5 Mw",
          "[leveller][strip]") {
  CHECK(MomentRatio(0.5) == 0.5);
  CHECK(MomentRatio(1.0) == 1.0);
  CHECK_THAT(MomentRatio(2.0), WithinRel(1.5 - 0.5 / 4.0, kRoundoff));  // SPEC.md §6.1
  CHECK_THAT(MomentRatio(1e4), WithinAbs(1.5, 1e-8));
  CHECK(MomentRatio(-3.0) == -MomentRatio(3.0));
}

TEST_CASE("The curvature ratio inverts the moment ratio", "[leveller][strip]") {
  for (double c : {0.1, 0.9, 1.0, 1.3, 2.0, 5.0, 20.0}) {
    CHECK_THAT(CurvatureRatio(MomentRatio(c)), WithinRel(c, 1e-10));
    CHECK_THAT(CurvatureRatio(MomentRatio(-c)), WithinRel(-c, 1e-10));
  }
  CHECK(std::isinf(CurvatureRatio(1.5)));
}

TEST_CASE("Springback leaves no residual curvature inside the elastic range and C - m beyond it",
          "[leveller][strip]") {
  CHECK(ResidualCurvatureRatio(0.8) == 0.0);
  CHECK_THAT(ResidualCurvatureRatio(2.0), WithinRel(2.0 - 1.375, kRoundoff));
}

TEST_CASE("A Masing reversal stays elastic over twice the elastic moment range",
          "[leveller][strip]") {
  MasingSection section;
  section.MoveTo(1.375);  // C = 2 on the skeleton
  REQUIRE_THAT(section.curvature(), WithinRel(2.0, kRoundoff));
  section.MoveTo(1.375 - 2.0);  // Δm = 2 Mw: still elastic, ΔC = Δm
  CHECK_THAT(section.curvature(), WithinRel(2.0 - 2.0, 1e-12));
  section.MoveTo(1.375 - 2.5);  // beyond: the doubled skeleton, ΔC = 2 g(Δm/2)
  CHECK_THAT(section.curvature(), WithinAbs(2.0 - 2.0 * CurvatureRatio(1.25), kRoundoff));
}

TEST_CASE("A reversal that passes the mirrored turning point rejoins the skeleton",
          "[leveller][strip]") {
  MasingSection section;
  section.MoveTo(1.3);
  section.MoveTo(-1.3);  // Masing branch ends on the mirrored skeleton point
  CHECK_THAT(section.curvature(), WithinRel(-CurvatureRatio(1.3), 1e-12));
  section.MoveTo(-1.4);  // memory rule: continue on the skeleton
  CHECK_THAT(section.curvature(), WithinRel(-CurvatureRatio(1.4), 1e-12));
}

TEST_CASE("The Masing work equals a numerical integral of m dC along a reversing path",
          "[leveller][strip]") {
  const double path[] = {1.4, -1.2, 1.1, -0.7, 0.0};
  MasingSection exact;
  MasingSection stepped;
  double numeric = 0.0;
  double m = 0.0;
  constexpr int kSteps = 20000;
  for (double target : path) {
    exact.MoveTo(target);
    const double start = m;
    for (int k = 1; k <= kSteps; ++k) {
      const double c0 = stepped.curvature();
      const double m0 = stepped.moment();
      stepped.MoveTo(start + (target - start) * k / kSteps);
      numeric += 0.5 * (m0 + stepped.moment()) * (stepped.curvature() - c0);  // trapezoid
    }
    m = target;
  }
  CHECK_THAT(exact.work(), WithinRel(numeric, 1e-6));
  CHECK(exact.work() > 0.0);  // plastic cycles dissipate
}

TEST_CASE("An elastic three-point bend plunges kappa m a^2 / 3 (beam closed form)",
          "[leveller][strip]") {
  const Strip strip = ThinStrip();
  const double m2 = 0.8;
  const auto pass = SimulateStripPass(strip, 200.0, {0.0, m2, 0.0, 0.0, 0.0, 0.0, 0.0});
  const double kappa_t = ElasticLimitCurvature_per_m(strip) * 1e-3;  // 1/mm
  const double a = 100.0;
  // Triangular moment over ±a: ½∫(a − |s|) κ ds = κt m a²/3.
  CHECK_THAT(pass.second_difference_mm[1], WithinRel(kappa_t * m2 * a * a / 3.0, kQuadratureRel));
  CHECK_THAT(pass.exit_residual_curvature_ratio, WithinAbs(0.0, kRoundoff));
}

TEST_CASE("The roll-collision limit follows the SPEC's formula", "[leveller][strip]") {
  // SPEC.md §6.1: D − sqrt((D + h)² − (t/2)²) = 180 − sqrt(186² − 100²).
  CHECK_THAT(CollisionLimitIntermesh_mm(180.0, 6.0, 200.0),
             WithinRel(180.0 - std::sqrt(24596.0), kRoundoff));
}

TEST_CASE("A flat-exit setpoint meets every contact with collinear upper rolls",
          "[leveller][strip]") {
  const Strip strip = ThinStrip();
  SetpointOptions options;
  options.entry_plastic_ratio = 0.6;
  const StripSetpoint s = ComputeStripSetpoint(strip, MachineData{}, options);
  REQUIRE(s.summary.converged);
  const auto& y = s.intermesh_mm;
  CHECK_THAT(y[2], WithinAbs(2.0 * y[1] - y[0], 1e-12));  // Y3 = 2 Y2 − Y1
  // Independent re-check of the five contact conditions (strip_mechanics.h).
  const auto d = SimulateStripPass(strip, 200.0, s.moment_ratio).second_difference_mm;
  const double h = strip.thickness_mm;
  constexpr double kContactMm = 1e-9;
  CHECK_THAT(d[1], WithinAbs(y[0] + h, kContactMm));
  CHECK_THAT(d[3], WithinAbs(y[1] + h, kContactMm));
  CHECK_THAT(d[5], WithinAbs(y[2] + h, kContactMm));
  CHECK_THAT(-d[2], WithinAbs(0.5 * (y[0] + y[1]) + h, kContactMm));
  CHECK_THAT(-d[4], WithinAbs(0.5 * (y[1] + y[2]) + h, kContactMm));
  CHECK_THAT(s.exit_residual_curvature_ratio, WithinAbs(0.0, 1e-6));
  // Entry target: C2 = 1/(1 − 0.6) = 2.5.
  CHECK_THAT(s.moment_ratio[1], WithinRel(MomentRatio(2.5), kRoundoff));
}

TEST_CASE("The seed's exit assumption M6 = Mw is available as a fixed exit curvature",
          "[leveller][strip]") {
  SetpointOptions options;
  options.entry_plastic_ratio = 0.5;
  options.exit = ExitCondition::kFixedCurvature;
  options.exit_curvature_ratio = 1.0;
  const StripSetpoint s = ComputeStripSetpoint(ThinStrip(), MachineData{}, options);
  REQUIRE(s.summary.converged);
  CHECK_THAT(s.moments_Nm[5], WithinRel(ElasticLimitMoment_Nm(ThinStrip()), kRoundoff));
}

TEST_CASE("Setpoint plunges plus thickness scale as 1/h for the same targets",
          "[leveller][strip]") {
  // Y_k + h = D_k ∝ κt = 2σs/(E h) when the curvature ratios are the same (strip_mechanics.h).
  Strip thin = ThinStrip();
  Strip thick = ThinStrip();
  thick.thickness_mm = 6.0;
  SetpointOptions options;
  const auto a = ComputeStripSetpoint(thin, MachineData{}, options);
  const auto b = ComputeStripSetpoint(thick, MachineData{}, options);
  for (int k = 0; k < 3; ++k) {
    CHECK_THAT((a.intermesh_mm[k] + 3.0) * 3.0, WithinRel((b.intermesh_mm[k] + 6.0) * 6.0, 1e-7));
  }
}

TEST_CASE("Setpoint work, torque and power are consistent with the moments", "[leveller][strip]") {
  const StripSetpoint s = ComputeStripSetpoint(ThinStrip(), MachineData{}, SetpointOptions{});
  CHECK(s.straightening_torque_kNm > 0.0);
  CHECK_THAT(s.total_force_kN, WithinRel(Sum(s.forces_kN), kRoundoff));
  CHECK_THAT(s.power_kW,
             WithinRel(DrivePower_kW(s.straightening_torque_kNm, s.total_force_kN, MachineData{}),
                       kRoundoff));
}

TEST_CASE("An invalid entry target is rejected naming the field", "[leveller][strip]") {
  SetpointOptions options;
  options.entry_plastic_ratio = 1.0;
  REQUIRE_THROWS_WITH(ComputeStripSetpoint(ThinStrip(), MachineData{}, options),
                      Catch::Matchers::Contains("entry_plastic_ratio must be in [0, 1)"));
}

TEST_CASE("A broken precondition is reported in every build type, not compiled out",
          "[leveller][strip]") {
  // An odd sample count breaks Simpson's rule: a bug in the caller, so std::logic_error naming
  // the invariant (assert would pass silently in the Release build CI runs).
  const std::array<double, 7> m{0.5, 1.2, 1.1, 1.0, 0.9, 0.8, 0.5};
  CHECK_THROWS_AS(SimulateStripPass(ThinStrip(), 200.0, m, 401), std::logic_error);
  CHECK_THROWS_WITH(
      SimulateStripPass(ThinStrip(), 200.0, m, 401),
      Catch::Matchers::Contains("Simpson") && Catch::Matchers::Contains("strip_mechanics.cpp"));
}
