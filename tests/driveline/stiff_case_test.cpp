// Issue 11: short and stiff phases (a near-step load, a fast drive loop, a heavily damped coupling)
// cost the exact solver about what an ordinary bite costs, and its answer agrees with CVODE run
// tight. The references are CVODE at rtol 1e-12 (an independent integrator) and, for the seeded
// extreme scenes, the exact solver's own clear success-or-failure contract.
#include <catch2/catch.hpp>
#include <chrono>
#include <cmath>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "extreme_scenes.h"
#include "hard_scenes.h"
#include "millkit/driveline/simulation.h"
#include "millkit/io/input_error.h"
#include "scene_builder.h"
#include "support/wall_guard.h"

using namespace millkit::driveline;
using namespace millkit::driveline::testing;
using Catch::Matchers::Contains;

namespace {

// Agreement with CVODE at rtol 1e-12, relative to the peak (issue 11 asks 1e-10 … 1e-7).
constexpr double kAgreement = 1e-7;
// Roundoff of a quantity read off the state, in units of its conditioning.
constexpr double kEpsilon = 2.220446049250313e-16;
constexpr double kRoundoffUlps = 64.0;

SimulationResult TightCvode(const Model& model) {
  SimulationOptions options;
  options.solver = SolverKind::kCvode;
  options.rtol = 1e-12;
  return Simulate(model, options);
}

// The largest difference of two sample matrices, relative to b's peak.
double Relative(const SampleMatrix& a, const SampleMatrix& b) {
  const double peak = std::max(b.cwiseAbs().maxCoeff(), 1e-300);
  return (a - b).cwiseAbs().maxCoeff() / peak;
}

// Self-consistency: the same run sampled three times as densely (other step lengths, other cached
// propagators, other event searches) gives the same states at the common times, within 1e-9 or
// within ten times what the two runs' error estimates say. Measured: 7.8e-8 at worst on the
// extreme scenes, on seeds with |M| h of 1e8 or more, where exp(M h) is conditioned like |M| h
// (the propagators are built in long double, which took seed 46 from 2e-4 to 5e-8); the estimate
// counts that conditioning and says so. Empty when the denser run fails (its reason in `why`).
std::optional<bool> SelfConsistent(const Model& model, double sample_rate_Hz,
                                   const SimulationResult& exact, std::string* why) {
  constexpr double kSelfConsistency = 1e-9;
  constexpr double kEstimateMargin = 10.0;
  SimulationOptions dense;
  std::vector<double> times;
  const double h = 1.0 / sample_rate_Hz;
  for (size_t k = 0; k < exact.time_s.size(); ++k) {
    times.push_back(exact.time_s[k]);
    if (k + 1 == exact.time_s.size()) break;
    times.push_back(exact.time_s[k] + h * (1.0 / 3.0));
    times.push_back(exact.time_s[k] + h * (2.0 / 3.0));
  }
  dense.output_times = times;
  const auto fine = Simulate(model, dense);
  if (!fine.summary.success) {
    *why = fine.summary.message;
    return std::nullopt;
  }
  SampleMatrix common(exact.time_s.size(), exact.mass_speed_rad_per_s.cols());
  for (int k = 0; k < common.rows(); ++k) common.row(k) = fine.mass_speed_rad_per_s.row(3 * k);
  return Relative(exact.mass_speed_rad_per_s, common) <=
         std::max(kSelfConsistency,
                  kEstimateMargin * (exact.summary.error_estimate + fine.summary.error_estimate));
}

// Against CVODE: the states agree within CVODE's own measured error (its run against one at
// rtol/10, floor 1e-6), or CVODE moves onto the exact answer as its tolerance is cut a hundredfold
// (CVODE's error estimate undershoots on stiff scenes; measured on extreme seeds 163, 172, 197,
// 219). The states, not the torques: a stiff damper reads its torque off the difference of two
// large speeds, where every solver's roundoff is amplified by d. Empty when CVODE gives no
// checked answer (it chatters, or runs out of steps).
std::optional<bool> AgreesWithCvode(const Model& model, const SimulationResult& exact) {
  SimulationOptions options;
  options.solver = SolverKind::kCvode;
  options.rtol = 1e-10;
  options.max_steps = 2'000'000;
  const auto cvode = SimulateCvodeChecked(model, options);
  if (!cvode.summary.success || !std::isfinite(cvode.summary.error_estimate)) return std::nullopt;
  const double difference = Relative(exact.mass_speed_rad_per_s, cvode.mass_speed_rad_per_s);
  if (difference <= std::max(1e-6, 10.0 * cvode.summary.error_estimate)) return true;
  options.rtol = 1e-12;
  const auto tighter = Simulate(model, options);
  return tighter.summary.success &&
         Relative(exact.mass_speed_rad_per_s, tighter.mass_speed_rad_per_s) <= difference / 3.0;
}

// An answer of the exact solver agrees with itself on a denser grid and with CVODE, when CVODE
// gives a checked answer (required when `cvode_answers`).
void CheckAnswer(const Model& model, double sample_rate_Hz, const SimulationResult& exact,
                 bool cvode_answers) {
  std::string why;
  const auto consistent = SelfConsistent(model, sample_rate_Hz, exact, &why);
  INFO(why);
  REQUIRE(consistent.has_value());
  CHECK(*consistent);
  const auto agrees = AgreesWithCvode(model, exact);
  if (cvode_answers) REQUIRE(agrees.has_value());
  if (agrees) CHECK(*agrees);
}

// The exact solver answers the extreme scene of `seed` in at most `max_steps` steps (its own
// count, substeps included), and the answer passes CheckAnswer.
void CheckAnswerInSteps(std::uint64_t seed, long max_steps, bool cvode_answers) {
  INFO("seed " << seed);
  const Scene scene = ExtremeSceneGenerator(seed).Next();
  const Model model(scene);
  const auto exact = Simulate(model, {});
  REQUIRE(exact.summary.success);
  CHECK(exact.summary.steps <= max_steps);
  CheckAnswer(model, scene.sample_rate_Hz, exact, cvode_answers);
}

void CheckAgainstCvode(const Scene& scene) {
  const Model model(scene);
  const auto exact = Simulate(model, {});
  const auto reference = TightCvode(model);
  REQUIRE(exact.summary.success);
  REQUIRE(reference.summary.success);
  CHECK(exact.summary.events == reference.summary.events);
  CHECK(exact.summary.error_estimate <= kAgreement);
  CHECK(RelativeDifference(exact.mass_speed_rad_per_s, reference.mass_speed_rad_per_s) <=
        kAgreement);
  if (scene.links.empty()) return;
  // A link torque c ψ + d (ω_from − ω_to) is read off the states: its roundoff is that of the
  // speeds times d, whatever the solver (about 1e-5 N·m at d = 1e10 and 1 rad/s). The comparison
  // allows that conditioning on top of kAgreement.
  double conditioning = 0.0;
  const double speed = reference.mass_speed_rad_per_s.cwiseAbs().maxCoeff();
  for (const Link& link : scene.links) {
    conditioning = std::max(conditioning, 2.0 * link.damping_Nms_per_rad * speed);
  }
  const double peak = reference.link_torque_Nm.cwiseAbs().maxCoeff();
  CHECK(RelativeDifference(exact.link_torque_Nm, reference.link_torque_Nm) <=
        kAgreement + kRoundoffUlps * kEpsilon * conditioning / peak);
}

}  // namespace

TEST_CASE("A load ramped over 1e-8 to 1e-13 s is integrated as a ramp and agrees with CVODE",
          "[hard][stiff]") {
  for (double rise : {1e-8, 1e-9, 1e-10, 1e-13}) {
    INFO("rise " << rise << " s");
    CheckAgainstCvode(NearStepScene(rise));
  }
}

TEST_CASE("A near-step load costs no more propagations than a step", "[hard][stiff]") {
  // Steps counted, not timed: the work of a run does not grow with 1 / rise.
  const auto step = Simulate(Model(NearStepScene(0.0)), {});
  const auto ramp = Simulate(Model(NearStepScene(1e-10)), {});
  REQUIRE(step.summary.success);
  REQUIRE(ramp.summary.success);
  CHECK(ramp.summary.steps <= step.summary.steps + 2);
}

TEST_CASE("A drive whose torque lag is 1e-6 or 1e-7 s runs at 10 Hz and agrees with CVODE",
          "[hard][stiff]") {
  for (double lag : {1e-6, 1e-7}) {
    INFO("lag " << lag << " s");
    CheckAgainstCvode(FastDriveScene(lag));
  }
}

TEST_CASE("A coupling damped at 1e8 or 1e10 N*m*s/rad agrees with CVODE", "[hard][stiff]") {
  for (double damping : {1e8, 1e10}) {
    INFO("damping " << damping);
    CheckAgainstCvode(HeavyDampingScene(damping));
  }
}

TEST_CASE("The work of a stiff run grows with log(|M| h), not with |M| h", "[hard][stiff]") {
  // Damping 1e6 … 1e12: |M| h grows a millionfold; the substeps may grow by the ladder's depth.
  const auto moderate = Simulate(Model(HeavyDampingScene(1e6)), {});
  const auto extreme = Simulate(Model(HeavyDampingScene(1e12)), {});
  REQUIRE(moderate.summary.success);
  REQUIRE(extreme.summary.success);
  CHECK(extreme.summary.steps <= 10 * moderate.summary.steps);
}

TEST_CASE("A heavily damped coupling or a fast drive loop costs the steps of a mild one",
          "[hard][stiff]") {
  // Steps counted, not timed. A stiff output step is one substep of the ladder once the fast
  // transient has decayed. Before 2026-11-28 it was one per level (about log2(|M| h)): a step
  // between output times is h only to the rounding of the times, which the substeps' fit took for
  // a remainder, so every step climbed the ladder from its finest level again (damping 1e10:
  // 3231 steps against 202 at damping 1e2; a drive lag of 1e-7 s: 1995 against 355 at 1 s).
  const auto mild = Simulate(Model(HeavyDampingScene(1e2)), {});
  REQUIRE(mild.summary.success);
  for (double damping : {1e6, 1e10, 1e12}) {
    INFO("damping " << damping);
    const auto heavy = Simulate(Model(HeavyDampingScene(damping)), {});
    REQUIRE(heavy.summary.success);
    CHECK(heavy.summary.steps <= 2 * mild.summary.steps);
  }
  const auto slow = Simulate(Model(FastDriveScene(1.0)), {});
  const auto fast = Simulate(Model(FastDriveScene(1e-7)), {});
  REQUIRE(slow.summary.success);
  REQUIRE(fast.summary.success);
  CHECK(fast.summary.steps <= 2 * slow.summary.steps);
}

TEST_CASE("A coupling damped between mild and stiff searches few of its steps for a crossing",
          "[hard][stiff]") {
  // Damping 3e3 and 7e3: |M| h 6 and 14, stepped on Taylor series (the stiff ladder takes over
  // above 16). Searched steps counted, not timed: a search expands the step in about |M| h pieces
  // and bisects each watched surface's polynomial. The surfaces' bound took the motion's growth
  // over a step as e^{|M| h} (at least 1.2e6 at 14), cleared none, and every step after the load
  // was searched (0.43 ms a run against 0.04 at damping 1e4); now the growth is sup |exp(m s)|
  // and the chord is bounded from the acceleration m v too, which a decayed mode leaves small.
  // Searched before: 128 of the 202 steps at 3e3, and at 7e3; now 4 and 10 (2 at damping 1e2).
  for (double damping : {3e3, 7e3}) {
    INFO("damping " << damping);
    const auto heavy = Simulate(Model(HeavyDampingScene(damping)), {});
    REQUIRE(heavy.summary.success);
    INFO("searched " << heavy.summary.searched_steps << " of " << heavy.summary.steps);
    CHECK(heavy.summary.searched_steps * 10 <= heavy.summary.steps);
    CheckAgainstCvode(HeavyDampingScene(damping));
  }
}

TEST_CASE("A link resting on its flank and pushed into contact from rest is seen by both solvers",
          "[hard][stiff]") {
  // The drive's torque builds through its lag, so the twist leaves the flank at third order in
  // time: CVODE's root function starts at exactly zero there (it used to miss the contact).
  Scene scene = TwoMassScene(1.0, 1.0, 1e4, 10.0, 0.01, 0.1, 1000.0);
  scene.links[0].gap_position = -1.0;
  scene.drive = Drive{0, -50.0, 10.0, 0.0, 1e-3, 100.0};
  CheckAgainstCvode(scene);
  const auto exact = Simulate(Model(scene), {});
  CHECK(exact.summary.events >= 1);
}

TEST_CASE("Tiny gaps pushed from rest by an I-only drive do not stall at t = 0", "[hard][stiff]") {
  // Generator seed 122: gaps of 4e-12 and 7e-6 rad resting on their back flanks, an I-only
  // drive whose torque builds through its lag, so the twists leave the flanks at fourth order in
  // time; contact, release and the damping cap meet at one point and the phases chattered
  // ("events do not advance time"). The solver now steps on blind to the chattering surfaces
  // for 1e-9 h, then watches them again. Reference: CVODE at rtol 1e-12.
  const Scene scene = ExtremeSceneGenerator(122).Next();
  REQUIRE(scene.drive.has_value());
  REQUIRE(scene.drive->kp == 0.0);
  const Model model(scene);
  const auto exact = Simulate(model, {});
  const auto reference = TightCvode(model);
  REQUIRE(exact.summary.success);
  REQUIRE(reference.summary.success);
  CHECK(RelativeDifference(exact.mass_speed_rad_per_s, reference.mass_speed_rad_per_s) <=
        kAgreement);
  CHECK(RelativeDifference(exact.link_torque_Nm, reference.link_torque_Nm) <= kAgreement);
}

TEST_CASE("Stiff runs whose switching surfaces stay near zero answer in few substeps",
          "[hard][stiff]") {
  // Found by tests/fuzz/driveline_fuzz (inputs: the bytes of these seeds): gaps of 2.5e-9 and
  // 2.6e-12 rad on couplings damped at 1e10 and 2e6, where a surface that reads d·ψ' stays within
  // a chord bound of zero while a fast mode elsewhere moves. The bound took the whole state's
  // acceleration (‖R_w‖₁ sup ‖exp(m s)‖∞ ‖m v‖∞): 20 million substeps (the per-run budget, 6.3 s,
  // a clear failure) and 11.7 million (3.1 s, answered). It now takes what the surface reads
  // (|R_w| E |m v|, E >= sup |exp(m s)| entry by entry): 41146 and 7716. The step counts are the
  // solver's own, not timings; CVODE answers both in milliseconds.
  for (const std::uint64_t seed :
       {std::uint64_t{0x26ab0d00000000cbULL}, std::uint64_t{0x4195fffd}}) {
    // CVODE chatters on the second (more than 10000 events at its default tolerances).
    CheckAnswerInSteps(seed, 100'000, /*cvode_answers=*/false);
  }
}

TEST_CASE("A heavily damped coupling's fast mode is bounded by its size, not its curvature",
          "[hard][stiff]") {
  // 2593 (fuzzer input 21 0a) and 0x105d (input 5d 10): couplings damped at 9.4e9 and 3.7e9
  // N·m·s/rad between masses turning together. The torque surface reads their speeds' difference
  // 3e8 times; the entry-by-entry bound read their common acceleration (3e13 each) instead, and the
  // substeps fell to h/512 while the surface stayed a hundred tolerances from zero: 1.7 million
  // substeps each (0.3-0.5 s). With the damper's fast mode apart (it decays, so its part of the
  // surface's curvature is bounded by its size) and the rest expanded to third order: 55429 and
  // 71831; with a stiff output step no longer cut at every level of the ladder (the test above),
  // 3352 and 15113, against 2000 output steps. The step counts are the solver's own, not timings.
  for (const std::uint64_t seed : {std::uint64_t{2593}, std::uint64_t{0x105d}}) {
    CheckAnswerInSteps(seed, 20'000, /*cvode_answers=*/true);
  }
}

TEST_CASE("A limited-law link riding the edge of contact under a heavy damper does not chatter",
          "[hard][stiff]") {
  // Found by tests/fuzz/driveline_fuzz (input 00 00 04 00): gaps of 1.2e-10 and 2.8e-9 rad on
  // couplings damped at 1.2e8 and 2.7e7, with a drive. From t = 6.66 ms the first link sits at
  // the corner ψ = b/2, ψ' = 0 of the limited law. Entering contact there, the motion before
  // (free) showed τd > τc, so the classification took the double spring, which pushed the light
  // mass back across S2 within 4e-13 s: +2c and +free alternated, each switch located exactly,
  // and the run ended at max_events (a million) after 2.7 s. At the corner the spring-damper
  // piece is taken now (kLinkSideFromMotion): 8 events. The exact answer and CVODE's (6254
  // events, stepping over the corner within its tolerance) agree.
  const Scene scene = ExtremeSceneGenerator(0x00040000).Next();
  REQUIRE(scene.contact == ContactLaw::kLimited);
  const Model model(scene);
  const auto exact = Simulate(model, {});
  REQUIRE(exact.summary.success);
  CHECK(exact.summary.events <= 100);
  CheckAnswer(model, scene.sample_rate_Hz, exact, /*cvode_answers=*/true);
}

TEST_CASE("Two limited-law links at the corner at once keep their regions at each other's events",
          "[hard][stiff]") {
  // Random line 7697 under a speed-PI drive (bench_random_lines --variant drive): two couplings
  // from the motor, each resting on its negative flank (gap_position −1) with no torque, so both
  // sit at the corner ψ = −b/2, ψ' = 0 when the bite starts. Each crossed S5 into the double
  // spring in turn, and at that event the other, on its own S5 to roundoff, took the default
  // side (the spring-damper piece) again: −sd/−2c and −2c/−sd swapped at every event until "events
  // do not advance time" after three escapes. A link the event does not involve keeps its region
  // there now (Model::Classify's `before`).
  Scene scene;
  scene.name = "two couplings at the corner";
  scene.duration_s = 0.3;
  scene.sample_rate_Hz = 1596.0;
  scene.contact = ContactLaw::kLimited;
  scene.initial_speed_rad_per_s = 10.0;
  scene.masses = {{"motor", 8598.7}, {"hub1", 32494.6},  {"roll2", 13200.3},
                  {"hub3", 3075.6},  {"roll4", 15019.3}, {"roll5", 22816.1}};
  scene.links = {MakeLink("motor_hub1", 0, 1, 1.1858e9, 403465.0, 0.0084380),
                 MakeLink("spindle2", 1, 2, 2.3168e9, 936804.0, 0.00065823),
                 MakeLink("motor_hub3", 0, 3, 2.0188e8, 32268.0, 0.029247),
                 MakeLink("spindle4", 3, 4, 6.6258e8, 187548.0, 0.026137),
                 MakeLink("spindle5", 0, 5, 2.5020e9, 764214.0, 0.0)};
  const double bite = 0.0518377;
  scene.torques = {Step(2, 0.0, -1.25015e7, bite, 0.0065400),
                   Step(4, 0.0, -1.35143e7, bite, 0.0148640),
                   Step(5, 0.0, -4.54645e6, bite, 0.0023683)};
  scene.drive = Drive{.mass = 0,
                      .speed_ref_rad_per_s = 10.0,
                      .kp = 757199.0,
                      .ki = 1.66698e7,
                      .lag_s = 0.00113559,
                      .limit_Nm = 1e12};
  const Model model(scene);
  const auto exact = Simulate(model, {});
  INFO(exact.summary.message);
  REQUIRE(exact.summary.success);
  CHECK(exact.summary.events <= 2000);
  CheckAnswer(model, scene.sample_rate_Hz, exact, /*cvode_answers=*/true);
}

TEST_CASE("A surface held within roundoff of zero by a heavily damped motion is crossed",
          "[hard][stiff]") {
  // Found by tests/fuzz/driveline_fuzz and the extreme scenes beyond the 300 above; each ended on
  // the stiff substep budget (200000 in one output step) after 0.3-3 s:
  //  - 2593 (fuzzer input 21 0a): a coupling damped at 9.4e9 between masses turning at the same
  //    speed; its torque S2 = τc + d ψ' reads their speeds' difference 3e8 times (scaled). As the
  //    torque fell through zero the substeps shortened toward it; below 2^-20 h both speeds
  //    changed by the same amount to the last bit, ψ' stopped drifting and S2 stayed 0.9997 of
  //    its tolerance past zero. The substeps' sum is compensated now: 12 events, as CVODE's.
  //  - 0x85002800 (fuzzer input 00 28 00 85), 331, 983: a surface past zero within its tolerance,
  //    which the ladder's propagator and the Taylor series of the same substep put on either
  //    side of −tolerance. One held so for 64 substeps, moving across, is crossed there, and the
  //    estimate takes what that may cost.
  for (const std::uint64_t seed :
       {std::uint64_t{2593}, std::uint64_t{0x85002800}, std::uint64_t{331}, std::uint64_t{983}}) {
    CAPTURE(seed);
    const Scene scene = ExtremeSceneGenerator(seed).Next();
    const Model model(scene);
    const auto exact = Simulate(model, {});
    INFO(exact.summary.message);
    REQUIRE(exact.summary.success);
    CheckAnswer(model, scene.sample_rate_Hz, exact, /*cvode_answers=*/true);
  }
  // 549 (|M| h = 6.4e10, a surface on it at t = 0): answered, with an estimate (2.7e-4) above
  // the exact target that covers its difference from CVODE (4.2e-6). CVODE at rtol 1e-10 and
  // 1e-12 agree to 5e-10: here the exact answer is the less accurate one, and says so.
  const Scene scene = ExtremeSceneGenerator(549).Next();
  const Model model(scene);
  const auto exact = Simulate(model, {});
  REQUIRE(exact.summary.success);
  CHECK(exact.summary.error_estimate > kExactErrorTarget);
  const auto cvode = TightCvode(model);
  REQUIRE(cvode.summary.success);
  CHECK(Relative(exact.mass_speed_rad_per_s, cvode.mass_speed_rad_per_s) <=
        exact.summary.error_estimate);
}

TEST_CASE("c/J past the double range is an input error, not a solver failure",
          "[hard][bad_input]") {
  Scene scene = TwoMassScene(1e-10, 1e-10, 1e300, 1.0, 0.0, 0.1, 1000.0);
  REQUIRE_THROWS_AS(Model(scene), millkit::InputError);
  REQUIRE_THROWS_WITH(Model(scene), Contains("overflows"));
}

TEST_CASE("CVODE's summary names its figure: the tolerance asked for, or a measured error",
          "[hard]") {
  const Model model(HeavyDampingScene(1e8));
  SimulationOptions options;
  options.solver = SolverKind::kCvode;
  const auto plain = Simulate(model, options);
  CHECK(plain.summary.error_kind == "requested tolerance");
  CHECK_THAT(plain.summary.BriefReport(), Contains("requested tolerance 1e-08"));
  const auto checked = SimulateCvodeChecked(model, options);
  REQUIRE(checked.summary.success);
  CHECK_THAT(checked.summary.error_kind, Contains("rtol/10"));
  // The measured figure is the difference from a tighter run: it must bound the difference from
  // the exact answer to within the tighter run's own error (about a tenth of it).
  const auto exact = Simulate(model, {});
  const double actual = RelativeDifference(checked.link_torque_Nm, exact.link_torque_Nm);
  CHECK(actual <= 2.0 * checked.summary.error_estimate + 1e-12);
}

TEST_CASE("Seeded extreme scenes end in an answer that agrees with CVODE, or a clear failure",
          "[hard][stiff][generator]") {
  // 300 scenes from the generator (extreme_scenes.h): 1–4 masses, stiffness 1…1e12, damping 0 or
  // 1e-3…1e10, gaps 1e-12…0.3 rad, rises 1e-10…1e-2 s, drive lags 1e-7…1 s, gear ratios.
  constexpr int kSeeds = 300;
  // A guard against hangs, far above the slowest case measured (0.8 s); not a speed claim. Scaled
  // (support/wall_guard.h) in a sanitizer build.
  constexpr double kWallGuard_s = 20.0 * millkit::testing::kWallGuardScale;
  // Clear failures still open: none since the stiff substeps bound each surface's motion by the
  // components it reads (|R_w| E |m v|, 2026-11-28); seeds 95 and 282 (a 2e-7 or 4e-11 rad gap on
  // a coupling damped at 4e8…1e10) stopped with "needs more than 200000 substeps" before.
  const std::set<int> kKnownFailures = {};
  // The exact solver against itself on a three times denser grid (SelfConsistent).
  // Known: the two runs differ by up to 4.7e-8 of peak speed while both estimates say 1e-11 or
  // less (README, Not done). Seed 170 agrees with itself since 2026-11-28 (the sharper bound);
  // 190 (3.1e-8 apart) since its substeps no longer stop at every level of the ladder
  // (2026-11-28, later): with fewer and longer substeps its estimate (the conditioning of
  // exp(m σ), which grows with σ) says 1.9e-9 where it said 4e-11.
  const std::set<int> kKnownEstimateMisses = {34};
  int answered = 0, failed = 0, compared = 0;
  for (int seed = 0; seed < kSeeds; ++seed) {
    INFO("seed " << seed);
    ExtremeSceneGenerator generator(seed);
    const Scene scene = generator.Next();
    std::optional<Model> model;
    try {
      model.emplace(scene);
    } catch (const millkit::InputError&) {
      continue;  // refused with a named rule: allowed
    }
    const auto started = std::chrono::steady_clock::now();
    const auto exact = Simulate(*model, {});
    const double wall =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    CHECK(wall <= kWallGuard_s);
    if (!exact.summary.success) {
      // A clear failure: a reason, and nothing pretending to be a result. Only the known cases
      // may fail (README, "Not done"); any other failure, and any known one that starts to
      // succeed, shows here.
      ++failed;
      CHECK_FALSE(exact.summary.message.empty());
      CHECK(kKnownFailures.count(seed) == 1);
      continue;
    }
    ++answered;
    REQUIRE(exact.link_torque_Nm.allFinite());
    REQUIRE(exact.mass_speed_rad_per_s.allFinite());
    REQUIRE(std::isfinite(exact.summary.error_estimate));
    INFO("estimate " << exact.summary.error_estimate);
    std::string why;
    const auto consistent = SelfConsistent(*model, scene.sample_rate_Hz, exact, &why);
    if (!consistent) {
      CHECK_FALSE(why.empty());
      CHECK(kKnownFailures.count(seed) == 1);
      continue;
    }
    // Honest estimates: the two runs differ by no more than their estimates say (with a floor).
    CHECK(*consistent == (kKnownEstimateMisses.count(seed) == 0));
    const auto agrees = AgreesWithCvode(*model, exact);
    if (!agrees) continue;
    ++compared;
    CHECK(*agrees);
  }
  WARN(answered << " answered, " << failed << " clear failures, " << compared
                << " compared with CVODE, of " << kSeeds);
}

// CVODE (the reference and `--solver cvode`) on a drive loop whose linear phase has a fast,
// lightly damped mode: −2.3e4 ± 2.95e6 i rad/s, 89.6° from the negative real axis, outside the
// stability wedge of BDF orders 3–5. Once the mode has decayed those orders go unstable on it as
// the step grows, and CVODE held its step near 0.6 / |λ| for the rest of the run: 4.9 million
// steps per simulated second (the driveline harness's input f7 fd: 23 million steps, 48 s, over
// its 4.7 s). Over the first 0.05 s (so that a regression fails in about 0.5 s): 234 413 steps
// before the order cap, 43 629 with it (nearly all in the transient of 139 events), and the
// same answer as the exact solver.
TEST_CASE("CVODE caps its order where a lightly damped fast mode has decayed", "[hard][stiff]") {
  const Scene scene = ExtremeSceneGenerator(0xfdf7).Next();
  const Model model(scene);
  std::vector<double> times;
  for (int k = 0; k / scene.sample_rate_Hz <= 0.05; ++k) times.push_back(k / scene.sample_rate_Hz);
  SimulationOptions exact_options;
  exact_options.output_times = times;
  const SimulationResult exact = Simulate(model, exact_options);
  REQUIRE(exact.summary.success);
  SimulationOptions options = exact_options;
  options.solver = SolverKind::kCvode;
  const SimulationResult cvode = Simulate(model, options);
  REQUIRE(cvode.summary.success);
  INFO("CVODE steps " << cvode.summary.steps);
  CHECK(cvode.summary.steps <= 100'000);
  CHECK(cvode.summary.event_times_s.size() == exact.summary.event_times_s.size());
  CHECK(Relative(cvode.mass_speed_rad_per_s, exact.mass_speed_rad_per_s) <= kAgreement);
}
