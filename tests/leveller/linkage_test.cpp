// Linkage kinematics (SPEC.md §6.2): forward checks, closed-form inverse, reach, dead centres,
// accuracy, hydraulic variant.
#include "millkit/leveller/linkage.h"

#include <catch2/catch.hpp>
#include <cmath>

using namespace millkit::leveller;
using Catch::Matchers::WithinAbs;
using Catch::Matchers::WithinRel;

namespace {

// The SPEC prints its checks to 4 decimals of a mm.
constexpr double kSpecDigitsMm = 5e-5;
// Round-trip accuracy demanded by issue 4.
constexpr double kRoundTripMm = 1e-9;
// Angle round trip away from the dead centres (∂Y/∂β ≥ 2e-3 mm/deg there).
constexpr double kRoundTripDeg = 1e-7;
// Grid step of the dense working-range grids.
constexpr double kGridStepDeg = 1.0;

const Linkage& DefaultLinkage() {
  static const Linkage linkage{LinkageGeometry{}};
  return linkage;
}

Intermesh<double> Y(double b1, double b2) {
  Intermesh<double> y;
  REQUIRE(DefaultLinkage().Forward(b1, b2, &y));
  return y;
}

}  // namespace

TEST_CASE("Eccentrics at 0 deg give the SPEC's -0.2080 mm on every upper roll",
          "[leveller][linkage]") {
  const auto y = Y(0.0, 0.0);  // SPEC.md §6.2 check
  CHECK_THAT(y.y1, WithinAbs(-0.2080, kSpecDigitsMm));
  CHECK_THAT(y.y2, WithinAbs(-0.2080, kSpecDigitsMm));
  CHECK_THAT(y.y3, WithinAbs(-0.2080, kSpecDigitsMm));
}

TEST_CASE("Eccentrics at 90 deg give the SPEC's -15 mm on every upper roll",
          "[leveller][linkage]") {
  const auto y = Y(90.0, 90.0);  // SPEC.md §6.2 check
  CHECK_THAT(y.y1, WithinAbs(-15.0, kSpecDigitsMm));
  CHECK_THAT(y.y2, WithinAbs(-15.0, kSpecDigitsMm));
  CHECK_THAT(y.y3, WithinAbs(-15.0, kSpecDigitsMm));
}

TEST_CASE("Roll 3# follows Y3 = 2 Y2 - Y1 and the beam stays rigid", "[leveller][linkage]") {
  for (double b1 = -90.0; b1 <= 90.0; b1 += 15.0) {
    for (double b2 = -90.0; b2 <= 90.0; b2 += 15.0) {
      Intermesh<double> y;
      LinkagePose<double> pose;
      REQUIRE(DefaultLinkage().Forward(b1, b2, &y, &pose));
      CHECK_THAT(y.y3, WithinAbs(2.0 * y.y2 - y.y1, 1e-12));
      CHECK_THAT(std::hypot(pose.f.x - pose.e.x, pose.f.y - pose.e.y), WithinRel(200.0, 1e-12));
      CHECK_THAT(std::hypot(pose.g.x - 950.0, pose.g.y - 650.0), WithinRel(500.0, 1e-12));
      CHECK_THAT(std::hypot(pose.k.x - pose.h.x, pose.k.y - pose.h.y), WithinRel(540.913, 1e-12));
      CHECK_THAT(std::hypot(pose.j.x - pose.g.x, pose.j.y - pose.g.y), WithinRel(540.913, 1e-12));
    }
  }
}

TEST_CASE("The closed-form inverse returns beta over a dense grid of the working range",
          "[leveller][linkage]") {
  // Principal branch: between the dead centres (about -89.98 and +90.02 deg), so the grid stops
  // one step short of -90; the edge itself has its own test.
  double worst_deg = 0.0;
  double worst_mm = 0.0;
  for (double b1 = -89.0; b1 <= 90.0; b1 += kGridStepDeg) {
    for (double b2 = -89.0; b2 <= 90.0; b2 += kGridStepDeg) {
      const auto y = Y(b1, b2);
      const AngleSetpoint s = DefaultLinkage().InverseClosedForm(y.y1, y.y2);
      REQUIRE(s.ok());
      worst_mm = std::max(worst_mm, s.residual_mm);
      if (std::abs(b1) <= 89.0 && std::abs(b2) <= 89.0) {
        worst_deg = std::max({worst_deg, std::abs(s.beta1_deg - b1), std::abs(s.beta2_deg - b2)});
      }
    }
  }
  CHECK(worst_mm <= kRoundTripMm);
  CHECK(worst_deg <= kRoundTripDeg);
}

TEST_CASE("forward(inverse(Y)) returns Y over a dense grid of reachable targets",
          "[leveller][linkage]") {
  double worst_mm = 0.0;
  int solved = 0;
  for (double y1 = -14.5; y1 <= 14.5; y1 += 0.25) {
    for (double y2 = -14.5; y2 <= 14.5; y2 += 0.25) {
      const AngleSetpoint s = DefaultLinkage().InverseClosedForm(y1, y2);
      // Corners of the square lie outside the reach; a target the closed form solves but the
      // forward map does not return would be a bug.
      REQUIRE(s.status != InverseStatus::kAssemblyMismatch);
      if (!s.ok()) continue;
      const auto y = Y(s.beta1_deg, s.beta2_deg);  // independent re-check
      worst_mm = std::max({worst_mm, std::abs(y.y1 - y1), std::abs(y.y2 - y2)});
      ++solved;
    }
  }
  CHECK(solved > 7500);  // about 59 % of the square (8046 targets) is inside the reach
  CHECK(worst_mm <= kRoundTripMm);
}

TEST_CASE("A target at the edge of reach (beta = 90 deg) is solved", "[leveller][linkage]") {
  const auto y = Y(90.0, 90.0);
  const AngleSetpoint s = DefaultLinkage().InverseClosedForm(y.y1, y.y2);
  REQUIRE(s.ok());
  CHECK(s.residual_mm <= kRoundTripMm);
  // 0.024 deg from the dead centre: Y changes by ~1e-9 mm per 1e-6 deg, the angle is looser.
  CHECK_THAT(s.beta1_deg, WithinAbs(90.0, 1e-6));
  CHECK_THAT(s.beta2_deg, WithinAbs(90.0, 1e-6));
}

TEST_CASE("Targets at the dead centres are solved with the forward map's accuracy",
          "[leveller][linkage]") {
  const auto& linkage = DefaultLinkage();
  // The lower dead centre of each eccentric at the deepest pose (K on line AH, J on line BG).
  const double dead1 = linkage.DeadCentresBeta1(-89.98, -89.98)[0];
  const double dead2 = linkage.DeadCentresBeta2(-89.98, -89.98)[0];
  REQUIRE(dead1 > -90.0);  // inside the working range in the default geometry
  const auto y = Y(dead1, dead2);
  const AngleSetpoint s = linkage.InverseClosedForm(y.y1, y.y2);
  REQUIRE(s.ok());
  CHECK(s.residual_mm <= kRoundTripMm);
  const auto accuracy = linkage.Accuracy(s.beta1_deg, s.beta2_deg, 0.01);
  CHECK(accuracy.dead_centre_distance_deg < 0.01);
}

TEST_CASE("The sliver beyond the dead centre maps back onto the principal branch",
          "[leveller][linkage]") {
  const auto y = Y(-90.0, -90.0);  // past the dead centre at about -89.977 deg
  const AngleSetpoint s = DefaultLinkage().InverseClosedForm(y.y1, y.y2);
  REQUIRE(s.ok());
  CHECK(s.beta1_deg > -89.98);  // the twin on the principal branch (about -89.954 deg)
  CHECK(s.residual_mm <= kRoundTripMm);
}

TEST_CASE("A target just outside the reach is refused, not clamped", "[leveller][linkage]") {
  const auto edge = Y(90.0, 90.0);
  constexpr double kJustOutsideMm = 1e-6;
  const AngleSetpoint s =
      DefaultLinkage().InverseClosedForm(edge.y1 - kJustOutsideMm, edge.y2 - kJustOutsideMm);
  CHECK(s.status == InverseStatus::kAngleOutsideRange);
  const AngleSetpoint far = DefaultLinkage().InverseClosedForm(40.0, 0.0);
  CHECK_FALSE(far.ok());
  const AngleSetpoint tilt = DefaultLinkage().InverseClosedForm(300.0, -300.0);
  CHECK(tilt.status == InverseStatus::kBeamTiltImpossible);
}

TEST_CASE("The automatic Jacobian matches central finite differences", "[leveller][linkage]") {
  // Truncation ~ Y''' h²/6 ≈ 1e-12, roundoff ~ 1e-13 mm / h ≈ 1e-9 mm/deg.
  constexpr double kStepDeg = 1e-4;
  constexpr double kFiniteDifferenceMmPerDeg = 1e-8;
  for (const auto& [b1, b2] : {std::pair{0.0, 0.0}, {30.0, -40.0}, {-70.0, 80.0}, {89.0, -89.0}}) {
    const auto jacobian = DefaultLinkage().Jacobian(b1, b2);
    const auto p1 = Y(b1 + kStepDeg, b2), m1 = Y(b1 - kStepDeg, b2);
    const auto p2 = Y(b1, b2 + kStepDeg), m2 = Y(b1, b2 - kStepDeg);
    CHECK_THAT(jacobian(0, 0),
               WithinAbs((p1.y1 - m1.y1) / (2 * kStepDeg), kFiniteDifferenceMmPerDeg));
    CHECK_THAT(jacobian(1, 0),
               WithinAbs((p1.y2 - m1.y2) / (2 * kStepDeg), kFiniteDifferenceMmPerDeg));
    CHECK_THAT(jacobian(2, 0),
               WithinAbs((p1.y3 - m1.y3) / (2 * kStepDeg), kFiniteDifferenceMmPerDeg));
    CHECK_THAT(jacobian(0, 1),
               WithinAbs((p2.y1 - m2.y1) / (2 * kStepDeg), kFiniteDifferenceMmPerDeg));
    CHECK_THAT(jacobian(1, 1),
               WithinAbs((p2.y2 - m2.y2) / (2 * kStepDeg), kFiniteDifferenceMmPerDeg));
    CHECK_THAT(jacobian(2, 1),
               WithinAbs((p2.y3 - m2.y3) / (2 * kStepDeg), kFiniteDifferenceMmPerDeg));
  }
}

TEST_CASE("The setpoint accuracy vanishes towards the dead centres", "[leveller][linkage]") {
  const double encoder_deg = 0.01;
  const auto mid = DefaultLinkage().Accuracy(0.0, 0.0, encoder_deg);
  const auto near_dead = DefaultLinkage().Accuracy(89.5, 89.5, encoder_deg);
  // Linear in the encoder resolution; ΔY ∝ cos β near the dead centre (15 mm · π/180 · 0.01 ≈ 2.6
  // µm per eccentric at β = 0).
  CHECK_THAT(DefaultLinkage().Accuracy(0.0, 0.0, 2 * encoder_deg).max_delta_y_mm,
             WithinRel(2 * mid.max_delta_y_mm, 1e-12));
  CHECK(mid.max_delta_y_mm > 0.002);
  CHECK(near_dead.max_delta_y_mm < 0.05 * mid.max_delta_y_mm);
  CHECK(near_dead.dead_centre_distance_deg < 1.0);
}

TEST_CASE("The hydraulic variant reproduces the eccentric poses from the rod lengths",
          "[leveller][linkage]") {
  const auto& linkage = DefaultLinkage();
  for (const auto& [b1, b2] : {std::pair{0.0, 0.0}, {30.0, -40.0}, {-60.0, 75.0}}) {
    Intermesh<double> y;
    LinkagePose<double> pose;
    REQUIRE(linkage.Forward(b1, b2, &y, &pose));
    // |AH| and |BG| of the eccentric pose, fed to the cylinder model.
    const double ah = std::hypot(pose.h.x - 150.0, pose.h.y - 1190.913);
    const double bg = std::hypot(pose.g.x - 450.0, pose.g.y - 1190.913);
    Intermesh<double> yh;
    REQUIRE(linkage.ForwardLengths(ah, bg, &yh));
    CHECK_THAT(yh.y1, WithinAbs(y.y1, kRoundTripMm));
    CHECK_THAT(yh.y2, WithinAbs(y.y2, kRoundTripMm));
    const LengthSetpoint lengths = linkage.InverseLengths(y.y1, y.y2, HydraulicRange{});
    REQUIRE(lengths.ok());
    CHECK_THAT(lengths.ah_mm, WithinAbs(ah, 1e-9));
    CHECK_THAT(lengths.bg_mm, WithinAbs(bg, 1e-9));
  }
  // Seed: 525.913 ≤ |BG| ≤ 555.913; a target needing more is refused.
  CHECK(linkage.InverseLengths(25.0, 25.0, HydraulicRange{}).status ==
        InverseStatus::kLengthOutsideRange);
}
