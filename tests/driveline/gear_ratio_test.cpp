// Link gear ratios (SPEC §1, scene.h): a scene with ratios runs as its reduced scene and reports
// every output in the units of the shaft it belongs to.
#include <catch2/catch.hpp>
#include <cmath>

#include "millkit/driveline/simulation.h"
#include "millkit/io/input_error.h"
#include "scene_builder.h"
#include "support/run_cli.h"

using namespace millkit::driveline;
using namespace millkit::driveline::testing;
using Catch::Matchers::Contains;
using Catch::Matchers::WithinRel;

namespace {
// Reducing by hand and in the model multiply by the same powers of the ratio: the two runs agree
// to a few ulps.
constexpr double kSameRun = 1e-13;
// As in closed_form_test: the exact solver holds closed forms to this fraction of the peak.
constexpr double kExactTolerance = 1e-9;

double MaxRelative(const SampleMatrix& a, const SampleMatrix& b, int col, double factor) {
  return (a.col(col) - factor * b.col(col)).cwiseAbs().maxCoeff() /
         (factor * b.col(col)).cwiseAbs().maxCoeff();
}

// Motor (from side, unreduced) geared i : 1 to a roll through a spindle with a gap; a load on the
// roll and a driving torque on the motor shaft, both in their own shaft's units.
Scene GearedTwoMass(double ratio) {
  Scene scene = TwoMassScene(50.0, 20.0, 1.0e5, 20.0, 0.01, 0.2, 4000.0);
  scene.links[0].ratio = ratio;
  scene.initial_speed_rad_per_s = 5.0;
  scene.torques = {Step(1, 0.0, -3000.0, 0.02, 0.005), Step(0, 0.0, 200.0, 0.05, 0.0)};
  return scene;
}
}  // namespace

TEST_CASE("A two-mass scene with a gear ratio equals its scene reduced by hand", "[ratio]") {
  // Reduced to the roll shaft: J_motor i², the motor torque · i; the spindle (on the roll side of
  // the gear) and the roll keep their values. Torques and twists of the spindle are in roll-shaft
  // units in both; the motor speed is i times the reduced one.
  const double i = 4.0;
  const Scene geared = GearedTwoMass(i);
  Scene by_hand = GearedTwoMass(1.0);
  by_hand.masses[0].inertia_kg_m2 *= i * i;
  by_hand.torques[1].values_Nm = {0.0, 200.0 * i};
  for (auto solver : {SolverKind::kExact, SolverKind::kCvode}) {
    SimulationOptions options;
    options.solver = solver;
    options.rtol = 1e-12;
    const auto a = Simulate(Model(geared), options);
    const auto b = Simulate(Model(by_hand), options);
    REQUIRE(a.summary.success);
    REQUIRE(b.summary.success);
    REQUIRE(a.summary.events > 0);  // the gap opens and closes
    CHECK(a.summary.events == b.summary.events);
    CHECK(MaxRelative(a.link_torque_Nm, b.link_torque_Nm, 0, 1.0) <= kSameRun);
    CHECK(MaxRelative(a.link_twist_rad, b.link_twist_rad, 0, 1.0) <= kSameRun);
    CHECK(MaxRelative(a.mass_speed_rad_per_s, b.mass_speed_rad_per_s, 0, i) <= kSameRun);
    CHECK(MaxRelative(a.mass_speed_rad_per_s, b.mass_speed_rad_per_s, 1, 1.0) <= kSameRun);
    CHECK(a.mass_speed_rad_per_s(0, 0) == i * 5.0);  // the motor turns i times the roll speed
  }
}

TEST_CASE("A geared two-mass line vibrates at the reduced closed-form frequency", "[ratio]") {
  // Undamped, no gap, load step T on the roll at t0: with J1' = i² J1 (the motor on the roll
  // shaft) the spindle torque is m(t) = −T J1' / (J1' + J2) (1 − cos ω (t − t0)),
  // ω² = c (1/J1' + 1/J2).
  const double i = 3.0, j1 = 40.0, j2 = 25.0, c = 2.0e5, torque = -1500.0, t0 = 0.01;
  Scene scene = TwoMassScene(j1, j2, c, 0.0, 0.0, 0.3, 5000.0);
  scene.links[0].ratio = i;
  scene.torques = {Step(1, 0.0, torque, t0)};
  const double j1_reduced = i * i * j1;
  const double omega = std::sqrt(c * (1.0 / j1_reduced + 1.0 / j2));
  const double amplitude = -torque * j1_reduced / (j1_reduced + j2);
  const Model model(scene);
  const auto result = Simulate(model, {});
  REQUIRE(result.summary.success);
  double worst = 0.0;
  for (size_t k = 0; k < result.time_s.size(); ++k) {
    const double t = result.time_s[k];
    const double expected = t < t0 ? 0.0 : amplitude * (1.0 - std::cos(omega * (t - t0)));
    worst = std::max(worst, std::abs(result.link_torque_Nm(static_cast<int>(k), 0) - expected));
  }
  CHECK(worst <= kExactTolerance * 2.0 * amplitude);
  // Kd of a suddenly applied load is 2 whatever the ratio (static torque in roll-shaft units).
  const auto factors = DynamicFactors(model, result);
  CHECK_THAT(factors[0].static_torque_Nm, WithinRel(amplitude, 1e-12));
  CHECK_THAT(factors[0].kd, WithinRel(2.0, 1e-5));
}

TEST_CASE("Gear ratios compose along the tree and convert each shaft's outputs", "[ratio]") {
  // motor —shaft— gear_in —stage1 (2:1)— gear_mid —stage2 (3:1)— roll: the motor and gear_in turn
  // 6 times, gear_mid 3 times the roll speed. The motor shaft's torque is in motor-shaft units:
  // 1/6 of its reduced value.
  Scene scene;
  scene.name = "two stages";
  scene.duration_s = 0.1;
  scene.sample_rate_Hz = 20000.0;
  scene.initial_speed_rad_per_s = 2.0;
  scene.masses = {{"motor", 2.0}, {"gear_in", 1.0}, {"gear_mid", 5.0}, {"roll", 300.0}};
  auto link = [](const char* name, int from, int to, double c, double ratio) {
    Link l;
    l.name = name;
    l.from = from;
    l.to = to;
    l.stiffness_Nm_per_rad = c;
    l.damping_Nms_per_rad = 1.0;
    l.ratio = ratio;
    return l;
  };
  scene.links = {link("shaft", 0, 1, 2.0e3, 1.0), link("stage1", 1, 2, 4.0e4, 2.0),
                 link("stage2", 2, 3, 5.0e5, 3.0)};
  scene.torques = {Step(3, 0.0, -600.0, 0.01, 0.002), Step(0, 0.0, 100.0, 0.0, 0.0)};
  const ShaftFactors k = ComputeShaftFactors(scene);
  CHECK(k.mass == std::vector<double>{6.0, 6.0, 3.0, 1.0});
  CHECK(k.link == std::vector<double>{6.0, 3.0, 1.0});

  const Scene reduced = ReducedScene(scene);
  CHECK(reduced.masses[0].inertia_kg_m2 == 72.0);
  CHECK(reduced.links[0].stiffness_Nm_per_rad == 2.0e3 * 36.0);
  CHECK(reduced.torques[1].values_Nm.back() == 600.0);
  const auto geared = Simulate(Model(scene), {});
  const auto plain = Simulate(Model(reduced), {});
  REQUIRE(geared.summary.success);
  CHECK(MaxRelative(geared.link_torque_Nm, plain.link_torque_Nm, 0, 1.0 / 6.0) <= kSameRun);
  CHECK(MaxRelative(geared.link_torque_Nm, plain.link_torque_Nm, 1, 1.0 / 3.0) <= kSameRun);
  CHECK(MaxRelative(geared.link_torque_Nm, plain.link_torque_Nm, 2, 1.0) <= kSameRun);
  CHECK(MaxRelative(geared.link_twist_rad, plain.link_twist_rad, 0, 6.0) <= kSameRun);
  CHECK(MaxRelative(geared.mass_speed_rad_per_s, plain.mass_speed_rad_per_s, 0, 6.0) <= kSameRun);
  CHECK(MaxRelative(geared.mass_speed_rad_per_s, plain.mass_speed_rad_per_s, 2, 3.0) <= kSameRun);
  // At t = 0 the line accelerates rigidly under the motor torque (100 N·m in motor-shaft units,
  // 600 on the roll shaft): the motor shaft passes the share of the inertia beyond it, reduced
  // J = 72 + 36 + 45 + 300 = 453 kg·m², of which 381 beyond the shaft.
  CHECK_THAT(geared.link_torque_Nm(0, 0), WithinRel(100.0 * 381.0 / 453.0, 1e-12));
}

TEST_CASE("A ratio that is not positive is rejected naming the key", "[ratio]") {
  for (double ratio : {0.0, -2.0, std::nan("")}) {
    Scene scene = GearedTwoMass(ratio);
    CHECK_THROWS_AS(Model(scene), millkit::InputError);
    CHECK_THROWS_WITH(Model(scene),
                      Contains("link 'shaft'") && Contains("'ratio'") && Contains("must be > 0"));
  }
}
