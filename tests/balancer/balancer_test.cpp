// The seed's case end to end: every number seed 002 prints (restated in SPEC.md §7) reproduced to
// its printed digits from the inputs alone, and the readings that were needed where the printed
// number does not follow from the seed's stated data or its garbled formula.
#include "millkit/balancer/balancer.h"

#include <catch2/catch.hpp>
#include <cmath>
#include <numbers>

#include "printed_value.h"

namespace bal = millkit::balancer;
using bal::testing::RoundsTo;
using Catch::Matchers::WithinAbs;
using Catch::Matchers::WithinRel;

namespace {

constexpr double kRadPerDeg = std::numbers::pi / 180.0;
// Arithmetic identities between doubles (not seed comparisons).
constexpr double kRoundOff = 1e-12;

const bal::BalancerResult& SeedResult() {
  static const bal::BalancerResult result = bal::CalculateBalancer(bal::SeedCase());
  return result;
}

}  // namespace

TEST_CASE("The seed's beta is arctan(190/600) rounded to 17.5 degrees", "[balancer][seed]") {
  // Seed 002 §1: "β = arctg 190/600 = 17,5°".
  CHECK_THAT(SeedResult().support.beta_rad / kRadPerDeg, RoundsTo(17.5, 1));
}

TEST_CASE("The support reactions reproduce the seed's P1 and P2", "[balancer][seed]") {
  // Seed 002 §1, SPEC.md §7: P1 = 65 975.6 N, P2 = 32 196 N.
  CHECK_THAT(SeedResult().support.p1_N, RoundsTo(65975.6, 1));
  CHECK_THAT(SeedResult().support.p2_N, RoundsTo(32196.0, 0));
}

TEST_CASE("The roller load and reactions reproduce the seed's q, N1 and N2", "[balancer][seed]") {
  // Seed 002 §2, SPEC.md §7: q = 134 644.1 N/m, N1 = N2 = 32 987.8 N.
  CHECK_THAT(SeedResult().roller.q_N_per_m, RoundsTo(134644.1, 1));
  CHECK_THAT(SeedResult().roller.n1_N, RoundsTo(32987.8, 1));
  CHECK_THAT(SeedResult().roller.n2_N, RoundsTo(32987.8, 1));
}

TEST_CASE("The roller moments reproduce the seed's values at 84 mm and 329 mm",
          "[balancer][seed]") {
  // Seed 002 §2, SPEC.md §7: M(x1 = 84 mm) = 2771 N·m, M(x2 = 329 mm) = 6812 N·m.
  CHECK_THAT(SeedResult().roller.moment_at_load_start_Nm, RoundsTo(2771.0, 0));
  CHECK_THAT(SeedResult().roller.moment_at_middle_Nm, RoundsTo(6812.0, 0));
}

TEST_CASE("The roller axle reproduces the seed's Pp, N3, N4, RA, RB and moment",
          "[balancer][seed]") {
  // Seed 002 §4, SPEC.md §7: Pp = 82 542.6 N, N3 = N4 = 41 271.3 N, RA = RB = 41 271.3 N,
  // M = 6644.7 N·m.
  const auto& axle = SeedResult().axle;
  CHECK_THAT(axle.pp_N, RoundsTo(82542.6, 1));
  CHECK_THAT(axle.n3_N, RoundsTo(41271.3, 1));
  CHECK_THAT(axle.n4_N, RoundsTo(41271.3, 1));
  CHECK_THAT(axle.ra_N, RoundsTo(41271.3, 1));
  CHECK_THAT(axle.rb_N, RoundsTo(41271.3, 1));
  CHECK_THAT(axle.moment_Nm, RoundsTo(6644.7, 1));
}

TEST_CASE("The cardan cross reproduces the seed's pin reaction and moment", "[balancer][seed]") {
  // Seed 002 §6, SPEC.md §7: G = 90 700.8 N (input), N = G/2 = 45 350.4 N, M = 7074.66 N·m.
  CHECK_THAT(SeedResult().cross.reaction_N, RoundsTo(45350.4, 1));
  CHECK_THAT(SeedResult().cross.moment_Nm, RoundsTo(7074.66, 2));
}

TEST_CASE("The seed's adopted pin diameter of 75 mm passes with the default safety factor",
          "[balancer][seed]") {
  // Seed 002 §6 adopts d = 75 mm after computing the minimum; with S = 1.5³ (top of every range)
  // the minimum is cbrt(7074.66 / (0.1 · 1370e6 / 3.375)) = 55.9 mm (closed form, printed by
  // the seed only as the adopted 75 mm).
  const auto& cross = SeedResult().cross;
  const double closed_form_min_diameter_m =
      std::cbrt(7074.6624 / (0.1 * 1370.0e6 / (1.5 * 1.5 * 1.5)));
  CHECK_THAT(cross.min_diameter_m, WithinRel(closed_form_min_diameter_m, kRoundOff));
  CHECK(cross.adopted_diameter_passes);
}

TEST_CASE("The seed's roller passes its contact check under the documented reading",
          "[balancer][seed]") {
  // Seed 002 §3 says the 100 mm roller satisfies the crushing check. With E = 2.1e11 Pa and
  // [σсм] = 850 MPa (balancer_input.h): Pр = (90 700.8 + 111 530) / 8, Pв = 1.6 · 0.8 · Pр,
  // σ = 0.418 sqrt(Pв E / (0.06 · 0.05)) = 629.1 MPa (closed form).
  const auto& contact = SeedResult().contact;
  const double roller_load_N = (90700.8 + 111530.0) / 8.0;
  const double closed_form_stress_Pa =
      0.418 * std::sqrt(1.6 * 0.8 * roller_load_N * 2.1e11 / (0.06 * 0.05));
  CHECK_THAT(contact.roller_load_N, WithinRel(roller_load_N, kRoundOff));
  CHECK_THAT(contact.stress_Pa, WithinRel(closed_form_stress_Pa, kRoundOff));
  CHECK(contact.passes);
  CHECK(SeedResult().AllChecksPass());
}

TEST_CASE("The seed's literal contact data would fail the check the seed says passes",
          "[balancer][reading]") {
  // Why the reading: with the printed E = 2.1e9 Pa and [σсм] = 8.5 MPa the stress is 62.9 MPa,
  // seven times the printed limit, so the printed pair cannot be what the seed checked.
  bal::BalancerInput literal = bal::SeedCase();
  literal.contact.elastic_modulus_Pa = 2.1e9;
  literal.contact.allowable_stress_Pa = 8.5e6;
  const auto contact = bal::CalculateBalancer(literal).contact;
  CHECK_THAT(contact.stress_Pa / 1e6, RoundsTo(62.9, 1));
  CHECK_FALSE(contact.passes);
}

TEST_CASE("The exact beta does not give the seed's P1, the half-degree rounding does",
          "[balancer][reading]") {
  // arctan(190/600) = 17.571°; P1 = Q / (4 cos(30° + 2 · 17.571°)) = 66 329.6 N, 0.54 % above the
  // printed 65 975.6 N. Only β = 17.5° reproduces the seed (and P2 does not depend on β).
  bal::BalancerInput exact = bal::SeedCase();
  exact.support.beta_rounding_deg = 0.0;
  const auto support = bal::CalculateBalancer(exact).support;
  CHECK_THAT(support.beta_rad / kRadPerDeg, RoundsTo(17.571, 3));
  CHECK_THAT(support.p1_N, RoundsTo(66329.6, 1));
  CHECK_THAT(support.p1_N, !RoundsTo(65975.6, 1));
  CHECK_THAT(support.p2_N, RoundsTo(32196.0, 0));
}

TEST_CASE("The axle moment follows from the seed's 0.161 m arm, not the stated 161.5 mm",
          "[balancer][reading]") {
  // Seed 002 §4: "при х = а = 161,5: Mи = N3·a = 41 271,3·0,161 = 6644,7 Н·м". With 0.1615 m the
  // moment is 6665.3 N·m; the reactions RA = RB = N3 do not depend on the overhang.
  bal::BalancerInput stated = bal::SeedCase();
  stated.axle.overhang_m = 0.1615;
  const auto axle = bal::CalculateBalancer(stated).axle;
  CHECK_THAT(axle.moment_Nm, RoundsTo(6665.3, 1));
  CHECK_THAT(axle.moment_Nm, !RoundsTo(6644.7, 1));
  CHECK_THAT(axle.ra_N, RoundsTo(41271.3, 1));
}

TEST_CASE("The garbled formulas read literally do not give the seed's printed numbers",
          "[balancer][reading]") {
  // The seed's text "q = P1/0,245*2" and "Pp = Q/2*cos(α+β)" lose their brackets; read as
  // written they give 538 576 N/m and 37 672 N, far from the printed values, which follow from
  // q = P1 / (2 · 0.245) and Pp = Q / (2 cos(α + β)) as implemented.
  const double p1_N = SeedResult().support.p1_N;
  const double literal_q = p1_N / 0.245 * 2.0;
  const double literal_pp = 111530.0 / 2.0 * std::cos((30.0 + 17.5) * kRadPerDeg);
  CHECK_THAT(literal_q, !RoundsTo(134644.1, 1));
  CHECK_THAT(literal_pp, !RoundsTo(82542.6, 1));
  CHECK_THAT(SeedResult().roller.q_N_per_m, WithinRel(p1_N / (2.0 * 0.245), kRoundOff));
}

TEST_CASE("The seed's case is exactly balanced and keeps its hinge gaps taken up",
          "[balancer][seed]") {
  // Default balancing force = the force for exact balance (balancer_input.h): δ = 0, seed 000's
  // band holds, gap_position = +1.
  const auto& gaps = SeedResult().gaps;
  CHECK_THAT(gaps.imbalance_percent, WithinAbs(0.0, kRoundOff));
  CHECK(gaps.state == bal::IdleGapState::kClosed);
  CHECK(gaps.gap_position == 1.0);
}

TEST_CASE("The calculator rejects a bad input with the key named", "[balancer][input]") {
  bal::BalancerInput input = bal::SeedCase();
  input.loads.rod_weight_share_N = -1.0;
  REQUIRE_THROWS_WITH(bal::CalculateBalancer(input),
                      Catch::Matchers::Contains("[load] key 'rod_weight_share_N'") &&
                          Catch::Matchers::Contains("must be > 0"));
}
