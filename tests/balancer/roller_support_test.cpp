// Physics of the roller support (roller_support.h) on its own: equilibrium, symmetry, limits and
// the preconditions. References are closed forms of beam statics.
#include "millkit/balancer/roller_support.h"

#include <catch2/catch.hpp>
#include <cmath>
#include <numbers>
#include <stdexcept>

namespace bal = millkit::balancer;
using Catch::Matchers::WithinAbs;
using Catch::Matchers::WithinRel;

namespace {

// Identities between doubles computed in different orders.
constexpr double kRoundOff = 1e-12;
constexpr double kP1_N = 65975.6;

bal::RollerBeam SeedBeam() { return bal::RollerBeam{}; }

}  // namespace

TEST_CASE("The roller's support reactions carry the whole distributed load", "[roller]") {
  // Vertical equilibrium: N1 + N2 = q · 2b = P1.
  const auto beam = SeedBeam();
  const auto r = bal::CalcRollerBending(kP1_N, beam);
  CHECK_THAT(r.n1_N + r.n2_N, WithinRel(kP1_N, kRoundOff));
  CHECK_THAT(r.q_N_per_m * 2.0 * beam.half_loaded_length_m, WithinRel(kP1_N, kRoundOff));
}

TEST_CASE("The roller moment peaks at midspan at P1 (2a + b) / 4", "[roller]") {
  // Closed form of a symmetric beam with a central uniform load: M_max = P1 (2a + b) / 4.
  const auto beam = SeedBeam();
  const double a = beam.support_offset_m;
  const double b = beam.half_loaded_length_m;
  const auto r = bal::CalcRollerBending(kP1_N, beam);
  CHECK_THAT(r.moment_at_middle_Nm, WithinRel(kP1_N * (2.0 * a + b) / 4.0, kRoundOff));
  const double step_m = 1e-3;
  CHECK(bal::RollerBendingMomentAt(kP1_N, beam, a + b - step_m) < r.moment_at_middle_Nm);
  CHECK(bal::RollerBendingMomentAt(kP1_N, beam, a + b + step_m) < r.moment_at_middle_Nm);
}

TEST_CASE("The roller moment vanishes at the supports and is symmetric", "[roller]") {
  const auto beam = SeedBeam();
  const double span = 2.0 * beam.support_offset_m + 2.0 * beam.half_loaded_length_m;
  CHECK(bal::RollerBendingMomentAt(kP1_N, beam, 0.0) == 0.0);
  CHECK(bal::RollerBendingMomentAt(kP1_N, beam, span) == 0.0);
  CHECK(bal::RollerBendingMomentAt(kP1_N, beam, -0.1) == 0.0);
  for (int i = 1; i < 20; ++i) {
    const double x = span * i / 40.0;
    CHECK_THAT(bal::RollerBendingMomentAt(kP1_N, beam, x),
               WithinRel(bal::RollerBendingMomentAt(kP1_N, beam, span - x), kRoundOff));
  }
}

TEST_CASE("The roller moment is continuous where the load starts", "[roller]") {
  // At x = a the parabola joins the straight line; both give N1 a.
  const auto beam = SeedBeam();
  const double a = beam.support_offset_m;
  const double tiny_m = 1e-9;
  const auto r = bal::CalcRollerBending(kP1_N, beam);
  CHECK_THAT(r.moment_at_load_start_Nm, WithinRel(r.n1_N * a, kRoundOff));
  CHECK_THAT(bal::RollerBendingMomentAt(kP1_N, beam, a + tiny_m),
             WithinAbs(r.n1_N * a, r.n1_N * tiny_m * 2.0));
}

TEST_CASE("A roller loaded over its whole span has the uniform-load moment q L^2 / 8", "[roller]") {
  // Limit a → 0: M_max = q (2b)² / 8 = P1 · 2b / 8.
  bal::RollerBeam beam;
  beam.support_offset_m = 0.0;
  const double length = 2.0 * beam.half_loaded_length_m;
  const auto r = bal::CalcRollerBending(kP1_N, beam);
  CHECK_THAT(r.moment_at_middle_Nm, WithinRel(kP1_N * length / 8.0, kRoundOff));
}

TEST_CASE("The two support reactions become equal as the rollers close up", "[support]") {
  // Limit lp → 0: β → 0 and P1 = Q / (4 cos α) = P2.
  bal::SupportGeometry geometry;
  geometry.roller_spacing_m = 1e-9;
  geometry.beta_rounding_deg = 0.0;
  const auto r = bal::CalcSupportReactions(111530.0, geometry);
  CHECK_THAT(r.p1_N, WithinRel(r.p2_N, 1e-8));
}

TEST_CASE("The support reactions scale linearly with the load", "[support]") {
  const bal::SupportGeometry geometry;
  const auto one = bal::CalcSupportReactions(1.0, geometry);
  const auto many = bal::CalcSupportReactions(111530.0, geometry);
  CHECK_THAT(many.p1_N, WithinRel(111530.0 * one.p1_N, kRoundOff));
  CHECK_THAT(many.p2_N, WithinRel(111530.0 * one.p2_N, kRoundOff));
}

TEST_CASE("Beta rounding snaps to the nearest step, and step zero keeps the exact angle",
          "[support]") {
  bal::SupportGeometry geometry;  // arctan(0.19 / 0.6) = 17.5713°
  const double deg = 180.0 / std::numbers::pi;
  geometry.beta_rounding_deg = 0.0;
  CHECK_THAT(bal::SupportBetaRad(geometry) * deg, WithinAbs(17.5713, 1e-4));
  geometry.beta_rounding_deg = 0.1;
  CHECK_THAT(bal::SupportBetaRad(geometry) * deg, WithinAbs(17.6, 1e-9));
  geometry.beta_rounding_deg = 0.5;
  CHECK_THAT(bal::SupportBetaRad(geometry) * deg, WithinAbs(17.5, 1e-9));
}

TEST_CASE("A support angle that makes cos(alpha + 2 beta) non-positive is refused", "[support]") {
  bal::SupportGeometry geometry;
  geometry.alpha_deg = 55.0;  // 55 + 2 · 17.5 = 90
  CHECK_THROWS_AS(bal::CalcSupportReactions(111530.0, geometry), std::invalid_argument);
  CHECK_THROWS_AS(bal::CalcSupportReactions(-1.0, bal::SupportGeometry{}), std::invalid_argument);
}

TEST_CASE("The roller axle is in equilibrium", "[axle]") {
  // ΣF = 0: RA + RB = N3 + N4; ΣM_A = 0: RB b − N4 (b + a) + N3 a = 0.
  const bal::RollerAxle axle;
  const auto r = bal::CalcRollerAxle(111530.0, bal::SupportGeometry{}, axle);
  const double a = axle.overhang_m;
  const double b = axle.support_span_m;
  CHECK_THAT(r.ra_N + r.rb_N, WithinRel(r.n3_N + r.n4_N, kRoundOff));
  CHECK_THAT(r.rb_N * b - r.n4_N * (b + a) + r.n3_N * a, WithinAbs(0.0, kRoundOff * r.pp_N));
  CHECK_THAT(r.n3_N + r.n4_N, WithinRel(r.pp_N, kRoundOff));
}

TEST_CASE("The line contact stress grows with the square root of the load", "[contact]") {
  const double one = bal::LineContactStressPa(1000.0, 2.1e11, 0.06, 0.05);
  const double four = bal::LineContactStressPa(4000.0, 2.1e11, 0.06, 0.05);
  CHECK_THAT(four, WithinRel(2.0 * one, kRoundOff));
  CHECK(bal::LineContactStressPa(0.0, 2.1e11, 0.06, 0.05) == 0.0);
  CHECK_THROWS_AS(bal::LineContactStressPa(1000.0, 2.1e11, 0.0, 0.05), std::invalid_argument);
}

TEST_CASE("A roller above its allowable contact stress fails the check", "[contact]") {
  bal::RollerContact contact;
  contact.allowable_stress_Pa = 500.0e6;  // below the seed case's 629 MPa
  const auto r = bal::CalcRollerContact(111530.0, 90700.8, contact);
  CHECK(r.stress_Pa > r.allowable_Pa);
  CHECK_FALSE(r.passes);
}
