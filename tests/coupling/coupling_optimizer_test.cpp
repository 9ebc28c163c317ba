// The coupling optimiser on a scene whose optimum is known by construction, checked against a
// dense scan; constraints at the returned point; inputs it must refuse.
//
// Scene: two masses J1, J2 joined by an undamped shaft without backlash; equal and opposite
// torques ±T ramp in over tr. The twist obeys ψ'' + ω² ψ = T(t) (1/J1 + 1/J2), ω² = c (1/J1 +
// 1/J2), the static torque is T, and after the ramp the torque oscillates about T with amplitude T
// |sin x| / x, x = ω tr / 2. So Kd(c) = 1 + |sin x| / x: the global minimum Kd = 1 sits at x = π (ω
// = 2π/tr), a V-shaped kink; on the bounds used below there is a second, worse basin at the stiff
// end (x ≈ 1.73π, Kd ≈ 1.137) behind a ridge (x ≈ 1.43π, Kd ≈ 1.217).
#include "millkit/optimize/coupling/coupling_optimizer.h"

#include <catch2/catch.hpp>
#include <cmath>
#include <limits>

#include "driveline/scene_builder.h"
#include "millkit/driveline/natural_frequencies.h"
#include "millkit/io/input_error.h"
#include "support/study_support.h"

using namespace millkit::coupling;
using namespace millkit::driveline;
using Catch::Matchers::Contains;
using millkit::InputError;
using millkit::driveline::testing::kPi;
using millkit::driveline::testing::Step;
using millkit::driveline::testing::TwoMassScene;

namespace {

constexpr double kJ1 = 1000.0, kJ2 = 500.0;
constexpr double kTorque = 1.0e4;  // N*m
constexpr double kRise = 0.02;     // s
constexpr double kSampleRate = 20000.0;
constexpr int kScanPoints = 241;  // dense log scan of the bounds

double Omega(double c) { return std::sqrt(c * (1.0 / kJ1 + 1.0 / kJ2)); }
double StiffnessAt(double omega) { return omega * omega / (1.0 / kJ1 + 1.0 / kJ2); }
double KdClosedForm(double c) {
  const double x = 0.5 * Omega(c) * kRise;
  return 1.0 + std::abs(std::sin(x)) / x;
}
// c* where ω tr = 2π: Kd = 1.
const double kOptimum = StiffnessAt(2.0 * kPi / kRise);

Scene RampScene(double c, double backlash = 0.0) {
  Scene scene = TwoMassScene(kJ1, kJ2, c, 0.0, backlash, 0.15, kSampleRate);
  scene.torques = {Step(0, 0.0, kTorque, 0.01, kRise), Step(1, 0.0, -kTorque, 0.01, kRise)};
  return scene;
}

CouplingProblem StiffnessProblem(const Scene& scene, double lower, double upper) {
  CouplingProblem problem;
  problem.file = "test";
  millkit::sweep::SweepDimension d;
  d.parameter = ParseSceneParameter(scene, "shaft.stiffness", "test");
  d.lower = lower;
  d.upper = upper;
  d.scale = millkit::sweep::Scale::kLog;
  problem.variables = {d};
  problem.counted_links = {0};
  return problem;
}

struct Scan {
  double step_log = 0.0;  // resolution: spacing in ln c
  double best_c = 0.0;
  double best_kd = 0.0;
};

// Dense scan of Kd over [lower, upper], keeping points with c >= keep_above only.
Scan DenseScan(const Scene& scene, double lower, double upper, double keep_above = 0.0) {
  Scan scan;
  scan.step_log = std::log(upper / lower) / (kScanPoints - 1);
  scan.best_kd = INFINITY;
  for (int i = 0; i < kScanPoints; ++i) {
    const double c = lower * std::exp(i * scan.step_log);
    if (c < keep_above) continue;
    Scene at = scene;
    at.links[0].stiffness_Nm_per_rad = c;
    const auto r = millkit::sweep::SimulateCase(at, millkit::sweep::StudySimulationOptions());
    REQUIRE(r.success);
    if (r.kd[0] < scan.best_kd) {
      scan.best_kd = r.kd[0];
      scan.best_c = c;
    }
  }
  return scan;
}

}  // namespace

TEST_CASE("the ramp scene's simulated Kd follows the closed form 1 + |sin x|/x",
          "[coupling][optimizer]") {
  for (double f : {0.3, 0.7, 1.0, 1.5, 2.5}) {
    const double c = f * kOptimum;
    const auto r =
        millkit::sweep::SimulateCase(RampScene(c), millkit::sweep::StudySimulationOptions());
    REQUIRE(r.success);
    // The largest sample lies within half a sample step of the crest: it is low by at most
    // A (1 − cos(ω h / 2)) <= A (ω h)² / 8, A = Kd − 1.
    const double h = 1.0 / kSampleRate;
    const double sampling = (KdClosedForm(c) - 1.0) * std::pow(Omega(c) * h, 2) / 8.0;
    CHECK(r.kd[0] <= KdClosedForm(c) + 1e-9);
    CHECK(r.kd[0] >= KdClosedForm(c) - sampling - 1e-9);
  }
}

TEST_CASE("the optimiser finds the known optimum within the dense scan's resolution",
          "[coupling][optimizer]") {
  const double lower = kOptimum / 4.0, upper = 3.0 * kOptimum;
  const Scene scene = RampScene(upper);
  const Scan scan = DenseScan(scene, lower, upper);
  // The construction itself: the scan's best lies next to c*.
  REQUIRE(std::abs(std::log(scan.best_c / kOptimum)) <= scan.step_log);

  const CouplingResult result = OptimizeCoupling(scene, StiffnessProblem(scene, lower, upper), {});
  INFO(result.summary.BriefReport());
  REQUIRE(result.summary.found);
  const double c = result.best.values[0];
  CHECK(std::abs(std::log(c / kOptimum)) <= scan.step_log);
  CHECK(result.best.kd_max <= scan.best_kd);
  CHECK(result.summary.recheck_difference == 0.0);
  CHECK(result.summary.global_evaluations + result.summary.local_evaluations ==
        result.summary.simulations + result.summary.infeasible_evaluations);
}

TEST_CASE("with a frequency limit above the free optimum the answer sits on the limit",
          "[coupling][optimizer]") {
  constexpr double kMinHz = 60.0;  // the free optimum has ω = 2π/tr: 50 Hz
  const double lower = kOptimum / 4.0, upper = 2.25 * kOptimum;
  const double c_limit = StiffnessAt(2.0 * kPi * kMinHz);
  const Scene scene = RampScene(upper);
  CouplingProblem problem = StiffnessProblem(scene, lower, upper);
  problem.min_frequency_Hz = kMinHz;
  const Scan scan = DenseScan(scene, lower, upper, c_limit);

  const CouplingResult result = OptimizeCoupling(scene, problem, {});
  INFO(result.summary.BriefReport());
  REQUIRE(result.summary.found);
  CHECK(result.best.lowest_frequency_Hz >= kMinHz);
  CHECK(result.best.constraints_met);
  CHECK(std::abs(std::log(result.best.values[0] / c_limit)) <= scan.step_log);
  CHECK(result.best.kd_max <= scan.best_kd);
  CHECK(result.summary.infeasible_evaluations > 0);
}

TEST_CASE("a twist limit becomes an exact lower stiffness bound that the answer respects",
          "[coupling][optimizer]") {
  constexpr double kBacklash = 0.002;  // rad: the twist counts b/2 on top of T/c
  const double lower = kOptimum / 4.0, upper = 2.25 * kOptimum;
  const double c_min = 1.44 * kOptimum;
  const Scene scene = RampScene(upper, kBacklash);
  CouplingProblem problem = StiffnessProblem(scene, lower, upper);
  problem.twist_limits = {{0, 0.5 * kBacklash + kTorque / c_min, kTorque}};

  const CouplingResult result = OptimizeCoupling(scene, problem, {});
  INFO(result.summary.BriefReport());
  REQUIRE(result.summary.found);
  // c_min = T / (max_twist − b/2): the subtraction amplifies max_twist's rounding by
  // max_twist / (max_twist − b/2); a few ulps on top for the divisions and the round-up.
  const double max_twist = problem.twist_limits[0].max_twist_rad;
  const double rounding =
      8.0 * std::numeric_limits<double>::epsilon() * max_twist / (max_twist - 0.5 * kBacklash);
  CHECK_THAT(result.lower[0], Catch::Matchers::WithinRel(c_min, rounding));
  CHECK(result.best.values[0] >= result.lower[0]);
  REQUIRE(result.best.twist_rad.size() == 1);
  CHECK(result.best.twist_rad[0] <= problem.twist_limits[0].max_twist_rad);
  CHECK(result.best.twist_rad[0] == 0.5 * kBacklash + kTorque / result.best.values[0]);
  // The gap changes the dynamics, so the scan (not the closed form) is the reference here.
  const Scan scan = DenseScan(scene, lower, upper, result.lower[0]);
  CHECK(result.best.kd_max <= scan.best_kd);
}

TEST_CASE("the coupling problem refuses what it cannot answer",
          "[coupling][optimizer][bad_input]") {
  const double lower = kOptimum / 4.0, upper = 2.25 * kOptimum;
  SECTION("a counted link without static torque (Kd undefined)") {
    Scene scene = RampScene(upper);
    millkit::testing::AppendMass(&scene, "idle", 100.0, "idle_link", 1);
    CouplingProblem problem = StiffnessProblem(scene, lower, upper);
    problem.counted_links = {0, 1};
    CHECK_THROWS_WITH(EffectiveBounds(scene, problem),
                      Contains("idle_link") && Contains("undefined"));
  }
  SECTION("a twist limit no stiffness within the bounds meets") {
    const Scene scene = RampScene(upper, 0.002);
    CouplingProblem problem = StiffnessProblem(scene, lower, upper);
    problem.twist_limits = {{0, 0.001, kTorque}};  // = b/2
    CHECK_THROWS_WITH(EffectiveBounds(scene, problem), Contains("half gap"));
    problem.twist_limits = {{0, 0.001 + kTorque / (2.0 * upper), kTorque}};
    CHECK_THROWS_WITH(EffectiveBounds(scene, problem), Contains("above the variable's upper"));
  }
  SECTION("a frequency limit above the stiffest bounds") {
    const Scene scene = RampScene(upper);
    CouplingProblem problem = StiffnessProblem(scene, lower, upper);
    problem.min_frequency_Hz = 1.01 * LowestNaturalFrequencyHz(scene);
    CHECK_THROWS_WITH(EffectiveBounds(scene, problem), Contains("cannot be met"));
  }
  SECTION("a variable that is not a stiffness or damping") {
    const Scene scene = RampScene(upper);
    CouplingProblem problem = StiffnessProblem(scene, lower, upper);
    problem.variables[0].parameter = ParseSceneParameter(scene, "a.inertia", "test");
    CHECK_THROWS_AS(EffectiveBounds(scene, problem), InputError);
  }
  SECTION("bad optimiser options") {
    CouplingOptions options;
    options.global_evaluations = 0;
    CHECK_THROWS_AS(options.Validate(), InputError);
    options = {};
    options.local_algorithm = millkit::optimize::Algorithm::kLdLbfgs;
    CHECK_THROWS_AS(options.Validate(), InputError);
  }
}
