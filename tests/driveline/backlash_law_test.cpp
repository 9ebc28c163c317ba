#include "millkit/driveline/backlash_law.h"

#include <catch2/catch.hpp>

#include "millkit/driveline/model.h"

using namespace millkit::driveline;
using Catch::Matchers::WithinAbs;

namespace {
constexpr double kC = 1.0e6, kD = 2.0e3, kB = 0.02;  // N·m/rad, N·m·s/rad, rad
constexpr double kTiny = 1e-12;                      // rad, just across a surface
constexpr double kTorqueTolerance = 1e-6;            // N·m
}  // namespace

TEST_CASE("Every law carries no torque inside the dead zone", "[backlash_law]") {
  for (auto law : {ContactLaw::kLimited, ContactLaw::kNoPull, ContactLaw::kLinear}) {
    for (double psi : {-kB / 2, -0.003, 0.0, 0.007, kB / 2}) {
      CHECK(BacklashTorque(law, kC, kD, kB, psi, 5.0) == 0.0);
    }
  }
}

TEST_CASE("The linear law is spring plus damper outside the dead zone and can pull",
          "[backlash_law]") {
  // Seed 000, eq. (4): m = c(ψ − b/2) + d ψ'.
  const double psi = kB / 2 + 0.001;
  CHECK_THAT(BacklashTorque(ContactLaw::kLinear, kC, kD, kB, psi, -3.0),
             WithinAbs(kC * 0.001 - kD * 3.0, kTorqueTolerance));
  CHECK(BacklashTorque(ContactLaw::kLinear, kC, kD, kB, psi, -3.0) < 0.0);
}

TEST_CASE("The no_pull law never pulls and jumps by d psi' at first contact", "[backlash_law]") {
  const double v = 2.0;
  CHECK(BacklashTorque(ContactLaw::kNoPull, kC, kD, kB, kB / 2, v) == 0.0);
  CHECK_THAT(BacklashTorque(ContactLaw::kNoPull, kC, kD, kB, kB / 2 + kTiny, v),
             WithinAbs(kD * v, 1e-3));
  CHECK(BacklashTorque(ContactLaw::kNoPull, kC, kD, kB, kB / 2 + 0.001, -10.0) == 0.0);
  CHECK(BacklashTorque(ContactLaw::kNoPull, kC, kD, kB, -kB / 2 - 0.001, 10.0) == 0.0);
}

TEST_CASE("The limited law is continuous at first contact", "[backlash_law]") {
  // Modelica ElastoBacklash: at ψ = b/2 with ψ' > 0, m = τc + min(τc, τd) = 2τc → 0.
  for (double v : {0.1, 1.0, 100.0}) {
    CHECK_THAT(BacklashTorque(ContactLaw::kLimited, kC, kD, kB, kB / 2 + kTiny, v),
               WithinAbs(0.0, 1e-5));
    CHECK_THAT(BacklashTorque(ContactLaw::kLimited, kC, kD, kB, -kB / 2 - kTiny, -v),
               WithinAbs(0.0, 1e-5));
  }
}

TEST_CASE("The limited law switches between spring-damper and doubled spring at tau_d = tau_c",
          "[backlash_law]") {
  const double psi = kB / 2 + 0.002;  // τc = 2000 N·m
  const double tau_c = kC * 0.002;
  const double v_equal = tau_c / kD;  // τd = τc
  CHECK_THAT(BacklashTorque(ContactLaw::kLimited, kC, kD, kB, psi, v_equal * 0.99),
             WithinAbs(tau_c + kD * v_equal * 0.99, kTorqueTolerance));
  CHECK_THAT(BacklashTorque(ContactLaw::kLimited, kC, kD, kB, psi, v_equal * 1.01),
             WithinAbs(2 * tau_c, kTorqueTolerance));
  // Continuous across the switch.
  CHECK_THAT(BacklashTorque(ContactLaw::kLimited, kC, kD, kB, psi, v_equal * (1 - 1e-12)),
             WithinAbs(BacklashTorque(ContactLaw::kLimited, kC, kD, kB, psi, v_equal * (1 + 1e-12)),
                       1e-6));
}

TEST_CASE("The limited law releases when tau_c + tau_d reaches zero, without a jump",
          "[backlash_law]") {
  const double psi = kB / 2 + 0.002;
  const double v_release = -kC * 0.002 / kD;
  CHECK(BacklashTorque(ContactLaw::kLimited, kC, kD, kB, psi, v_release * 1.001) == 0.0);
  CHECK_THAT(BacklashTorque(ContactLaw::kLimited, kC, kD, kB, psi, v_release * 0.999),
             WithinAbs(0.0, 3.0));
}

TEST_CASE("Each mode's coefficients reproduce the law in the region of that mode",
          "[backlash_law]") {
  struct Case {
    double psi, v;
    LinkMode mode;
  };
  const Case cases[] = {{0.015, 0.1, LinkMode::kPosSpringDamper},
                        {0.011, 10.0, LinkMode::kPosDoubleSpring},
                        {-0.015, -0.1, LinkMode::kNegSpringDamper},
                        {-0.011, -10.0, LinkMode::kNegDoubleSpring}};
  for (const auto& c : cases) {
    const auto k = CoefficientsOf(c.mode, kC, kD, kB);
    CHECK_THAT(
        k.kpsi * c.psi + k.kv * c.v + k.k0,
        WithinAbs(BacklashTorque(ContactLaw::kLimited, kC, kD, kB, c.psi, c.v), kTorqueTolerance));
  }
}

TEST_CASE("A link without backlash creates no switching surfaces", "[backlash_law]") {
  // SPEC §2.2: b = 0 is a plain spring-damper; only the b > 0 link gets surfaces (6 each).
  Scene scene;
  scene.duration_s = 0.1;
  scene.sample_rate_Hz = 1000;
  scene.masses = {{"a", 1.0}, {"b", 1.0}, {"c", 1.0}};
  scene.links = {{"stiff", 0, 1, 100.0, 1.0, 0.0, -1.0}, {"gap", 1, 2, 100.0, 1.0, 0.01, -1.0}};
  const Model model(scene);
  CHECK(model.surface_count() == 6);
  CHECK(model.state_size() == 2 + 3);  // two twists, three speeds, no drive states
}
