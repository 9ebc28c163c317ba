// Closed-form references (SPEC §2.7): two-mass free vibration, time through a gap, energy
// conservation without damping, static torques and the quasi-static initial state.
#include <catch2/catch.hpp>
#include <cmath>

#include "millkit/driveline/simulation.h"
#include "scene_builder.h"
#include "support/run_cli.h"

using namespace millkit::driveline;
using namespace millkit::driveline::testing;
using Catch::Matchers::WithinAbs;
using Catch::Matchers::WithinRel;

namespace {
// The exact solver is exact up to roundoff: closed forms hold to this fraction of the peak.
constexpr double kExactTolerance = 1e-9;

double Energy(const Scene& scene, const SimulationResult& r, int k) {
  double e = 0.0;
  for (size_t i = 0; i < scene.masses.size(); ++i) {
    const double w = r.mass_speed_rad_per_s(k, static_cast<int>(i));
    e += 0.5 * scene.masses[i].inertia_kg_m2 * w * w;
  }
  for (size_t l = 0; l < scene.links.size(); ++l) {
    const double psi = r.link_twist_rad(k, static_cast<int>(l));
    const double over = std::max(0.0, std::abs(psi) - 0.5 * scene.links[l].backlash_rad);
    e += 0.5 * scene.links[l].stiffness_Nm_per_rad * over * over;
  }
  return e;
}
}  // namespace

TEST_CASE("Two-mass free vibration follows the closed form in frequency and amplitude",
          "[closed_form]") {
  // datasets/scenes/two_mass_step.toml: ψ(t) = (T/c)(1 − cos ω (t − t0)), ω² = c (1/J1 + 1/J2).
  const Model model(LoadScene(millkit::testing::SourcePath("datasets/scenes/two_mass_step.toml")));
  const double torque = 1000.0, c = 1.0e6, t0 = 0.01;
  const double omega = std::sqrt(c * (1.0 / 1000.0 + 1.0 / 500.0));
  for (auto solver : {SolverKind::kExact, SolverKind::kCvode}) {
    SimulationOptions options;
    options.solver = solver;
    options.rtol = 1e-12;
    const auto result = Simulate(model, options);
    REQUIRE(result.summary.success);
    const double tolerance = solver == SolverKind::kExact ? kExactTolerance : 1e-8;
    double worst = 0.0;
    for (size_t k = 0; k < result.time_s.size(); ++k) {
      const double t = result.time_s[k];
      const double expected = t < t0 ? 0.0 : torque * (1.0 - std::cos(omega * (t - t0)));
      worst = std::max(worst, std::abs(result.link_torque_Nm(static_cast<int>(k), 0) - expected));
    }
    CHECK(worst <= tolerance * 2.0 * torque);
  }
}

TEST_CASE("The dynamic factor of a suddenly applied load on an undamped shaft is 2",
          "[closed_form]") {
  const Model model(LoadScene(millkit::testing::SourcePath("datasets/scenes/two_mass_step.toml")));
  const auto factors = DynamicFactors(model, Simulate(model, {}));
  // Peak between samples: the sampled peak is low by at most 1 − cos(ω h / 2) ≈ 4e-6.
  CHECK_THAT(factors[0].kd, WithinRel(2.0, 1e-5));
  CHECK_THAT(factors[0].static_torque_Nm, WithinRel(1000.0, 1e-12));
}

TEST_CASE("A link closes its gap after b / delta-omega", "[closed_form]") {
  // Two free masses, relative speed Δω, the link resting on its back flank (ψ = −b/2).
  const double b = 0.02, delta_omega = 1.5;
  const Model model(TwoMassScene(10.0, 5.0, 1e5, 50.0, b, 0.05, 2000.0));
  Eigen::VectorXd x(3);
  x << -b / 2, delta_omega, 0.0;
  for (auto solver : {SolverKind::kExact, SolverKind::kCvode}) {
    SimulationOptions options;
    options.solver = solver;
    options.rtol = 1e-12;
    options.initial_state = x;
    const auto result = Simulate(model, options);
    REQUIRE(result.summary.success);
    REQUIRE(!result.summary.event_times_s.empty());
    const double tolerance = solver == SolverKind::kExact ? 1e-14 : 1e-9;
    CHECK_THAT(result.summary.event_times_s.front(), WithinAbs(b / delta_omega, tolerance));
  }
}

TEST_CASE("Energy is conserved without damping over a thousand bounce periods", "[closed_form]") {
  // Free flight across the gap and elastic contact on each flank, no damping, no load:
  // E = ½ Σ J ω² + ½ c (|ψ| − b/2)² stays constant. Period 2 (b/Δω + π/√(2c/J)) ≈ 0.0844 s.
  const double b = 0.01, delta_omega = 0.5, c = 1e4;
  const double period = 2.0 * (b / delta_omega + kPi / std::sqrt(2.0 * c));
  Scene scene = TwoMassScene(1.0, 1.0, c, 0.0, b, 1000.0 * period, 200.0);
  const Model model(scene);
  Eigen::VectorXd x(3);
  x << 0.0, delta_omega, 0.0;
  SimulationOptions options;
  options.initial_state = x;
  const auto result = Simulate(model, options);
  REQUIRE(result.summary.success);
  CHECK(result.summary.events >= 2000);
  const double e0 = Energy(scene, result, 0);
  double drift = 0.0;
  for (size_t k = 0; k < result.time_s.size(); ++k) {
    drift = std::max(drift, std::abs(Energy(scene, result, static_cast<int>(k)) - e0));
  }
  // Stated drift bound: 1e-9 of the energy over 1000 periods (measured ~1e-12).
  CHECK(drift <= 1e-9 * e0);
}

TEST_CASE("Static torques follow the rigid-body split of the final loads", "[closed_form]") {
  // SPEC §2.5 by hand for datasets/scenes/mill5_bite.toml: ε = ΣM / ΣJ = −280000 / 43000.
  const Scene scene = LoadScene(millkit::testing::SourcePath("datasets/scenes/mill5_bite.toml"));
  const auto m = StaticLinkTorques(scene);
  const double eps = -280000.0 / 43000.0;
  CHECK_THAT(m[0], WithinRel(13000.0 * eps + 280000.0, 1e-12));  // motor_shaft: B = all but motor
  CHECK_THAT(m[1], WithinRel(5000.0 * eps + 280000.0, 1e-12));   // main_coupling
  CHECK_THAT(m[2], WithinRel(1000.0 * eps + 150000.0, 1e-12));   // upper_spindle
  CHECK_THAT(m[3], WithinRel(1000.0 * eps + 130000.0, 1e-12));   // lower_spindle
}

TEST_CASE("A line loaded in equilibrium at t = 0 starts at its quasi-static twist and stays",
          "[closed_form]") {
  // Equal and opposite torques from t = 0: ε = 0, the link carries T at ψ = b/2 + T/c.
  const double torque = 500.0, c = 1e5, b = 0.01;
  Scene scene = TwoMassScene(2.0, 3.0, c, 10.0, b, 0.1, 1000.0);
  scene.torques = {Step(0, torque, torque, 0.0), Step(1, -torque, -torque, 0.0)};
  const auto result = Simulate(Model(scene), {});
  REQUIRE(result.summary.success);
  CHECK(result.summary.events == 0);
  CHECK_THAT(result.link_twist_rad.col(0).minCoeff(), WithinRel(b / 2 + torque / c, 1e-12));
  CHECK_THAT(result.link_twist_rad.col(0).maxCoeff(), WithinRel(b / 2 + torque / c, 1e-12));
  CHECK_THAT(result.link_torque_Nm.col(0).maxCoeff(), WithinRel(torque, 1e-10));
}

TEST_CASE("An unloaded link with backlash starts at gap_position times b/2", "[closed_form]") {
  Scene scene = TwoMassScene(2.0, 3.0, 1e5, 10.0, 0.02, 0.01, 1000.0);
  scene.links[0].gap_position = 0.25;
  const auto result = Simulate(Model(scene), {});
  CHECK(result.link_twist_rad(0, 0) == 0.25 * 0.01);
  CHECK(result.link_torque_Nm.cwiseAbs().maxCoeff() == 0.0);
}
