// Identification an engineer can trust (issue 12): fits on lines nobody tuned the fit on end
// within 3 standard errors of the truth or say they are not sure; each verdict on a constructed
// case; degenerate records end in a verdict, never a crash or a stray file.
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "driveline/scene_builder.h"
#include "fit_fixture.h"
#include "identify/random_line.h"
#include "millkit/driveline/scene_parameter.h"
#include "support/run_cli.h"

namespace millkit::identify {
namespace {

using Catch::Matchers::Contains;
using testing::Mill5Config;
using testing::Mill5Record;
using testing::Mill5Scene;

// The three-mass line: motor 20 000, pinion 4 000, roll 1 500 kg·m²; main shaft 3e8
// N·m/rad, damping 40 000, gap 4.5 mrad; spindle 1.3e7, damping 7 500, gap 30 mrad; load
// −120 kN·m from 45.5 ms, rise 8 ms.
driveline::Scene ThreeMassTruth() {
  driveline::Scene scene;
  scene.name = "three-mass line";
  scene.duration_s = 0.3;
  scene.sample_rate_Hz = 2500.0;
  scene.initial_speed_rad_per_s = 10.0;
  scene.masses = {{"motor", 20000.0}, {"pinion", 4000.0}, {"roll", 1500.0}};
  driveline::Link shaft;
  shaft.name = "main_shaft";
  shaft.from = 0;
  shaft.to = 1;
  shaft.stiffness_Nm_per_rad = 3e8;
  shaft.damping_Nms_per_rad = 40000.0;
  shaft.backlash_rad = 0.0045;
  driveline::Link spindle;
  spindle.name = "spindle";
  spindle.from = 1;
  spindle.to = 2;
  spindle.stiffness_Nm_per_rad = 1.3e7;
  spindle.damping_Nms_per_rad = 7500.0;
  spindle.backlash_rad = 0.030;
  scene.links = {shaft, spindle};
  driveline::TorqueSource load;
  load.name = "roll load";
  load.mass = 2;
  load.times_s = {0.0455, 0.0535};
  load.values_Nm = {0.0, -120000.0};
  scene.torques = {load};
  driveline::ValidateScene(scene);
  return scene;
}

Oscillogram ThreeMassRecord(const driveline::Scene& truth, unsigned long seed) {
  RecordSpec spec;
  spec.defects.sample_rate_Hz = 2500.0;
  spec.defects.noise_fraction = 0.015;
  spec.defects.bits = 12;
  spec.defects.lowpass_Hz = 600.0;
  spec.defects.seed = seed;
  spec.channels = {{"main_shaft", 0, 1.04, 900.0}, {"spindle", 1, 0.98, -1500.0}};
  return GenerateRecord(truth, spec);
}

// Fit settings shaped like the bundled ones: the engineer's prior (dampings and gaps 20–30 % off,
// the bite at 50 ms), bounds a worn line allows, the recorder filter known.
FitConfig ThreeMassConfig(const driveline::Scene& prior, const Oscillogram& record) {
  FitConfig config;
  const auto add = [&](const std::string& name, double lower, double upper) {
    FreeParameter p;
    p.parameter = driveline::ParseSceneParameter(prior, name, "test");
    p.start = p.parameter.Get(prior);
    p.lower = lower;
    p.upper = upper;
    p.scan = true;
    p.per_record = name == "bite_time";
    config.free.push_back(p);
  };
  add("main_shaft.damping", 5000.0, 3e5);
  add("spindle.damping", 1000.0, 5e4);
  add("main_shaft.backlash", 0.001, 0.012);
  add("spindle.backlash", 0.01, 0.06);
  add("bite_time", 0.03, 0.07);
  for (const std::string column : {"main_shaft", "spindle"}) {
    ChannelSpec c;
    c.column = c.link = column;
    c.link_index = prior.LinkIndex(column);
    c.lowpass_Hz = 600.0;
    config.channels.push_back(c);
  }
  config.window_start_s = record.time_s.front();
  config.window_end_s = record.time_s.back();
  return config;
}

driveline::Scene ThreeMassPrior() {
  driveline::Scene prior = ThreeMassTruth();
  prior.links[0].damping_Nms_per_rad = 52000.0;
  prior.links[1].damping_Nms_per_rad = 5500.0;
  prior.links[0].backlash_rad = 0.0055;
  prior.links[1].backlash_rad = 0.024;
  driveline::ParseSceneParameter(prior, "bite_time", "test").Set(0.05, &prior);
  return prior;
}

// Largest |value − truth| / standard error over the identifiable parameters.
double WorstZ(const FitResult& fit, const driveline::Scene& truth, std::string* which) {
  double worst = 0.0;
  for (const auto& p : fit.parameters) {
    if (!p.identifiable) continue;
    const double t = driveline::ParseSceneParameter(truth, p.name, "test").Get(truth);
    const double z = std::abs(p.value - t) / p.standard_error;
    if (!(z <= worst)) {
      worst = z;
      *which = p.name;
    }
  }
  return worst;
}

// A random line fitted with the defaults, and how far its worst identifiable parameter is from
// the truth, in its standard errors.
struct DefaultFit {
  explicit DefaultFit(const RandomLineCase& line)
      : fit(Fit(line.prior, line.record, line.config, FitOptions{})) {
    REQUIRE(fit.summary.success);
    worst = WorstZ(fit, line.truth, &which);
  }
  FitResult fit;
  std::string which;
  double worst = 0.0;
};

// The fitted `name` lies within `k` of its standard errors of the truth's value.
void CheckWithinStandardErrors(const FitResult& fit, const driveline::Scene& truth_scene,
                               const std::string& name, double k) {
  for (const auto& p : fit.parameters) {
    if (p.name != name) continue;
    const double truth =
        driveline::ParseSceneParameter(truth_scene, p.name, "test").Get(truth_scene);
    INFO(p.value << " +- " << p.standard_error << ", truth " << truth);
    CHECK(std::abs(p.value - truth) < k * p.standard_error);
  }
}

// Whether some warning of the fit contains `text`.
bool Says(const FitResult& fit, const std::string& text) {
  return std::any_of(fit.summary.warnings.begin(), fit.summary.warnings.end(),
                     [&](const std::string& w) { return w.find(text) != std::string::npos; });
}

// A random line fitted twice: with one check switched off by `switch_off`, and with `with` (the
// defaults unless given); and how far the first is from the truth.
struct WithAndWithout {
  FitResult without;
  FitResult with;
  double worst_without = 0.0;  // in its standard errors
  std::string which_without;
};
WithAndWithout FitWithAndWithout(const RandomLineCase& c, void (*switch_off)(FitOptions*),
                                 const FitOptions& with = FitOptions{}) {
  FitOptions without = with;
  switch_off(&without);
  WithAndWithout fits;
  fits.without = Fit(c.prior, c.record, c.config, without);
  fits.with = Fit(c.prior, c.record, c.config, with);
  REQUIRE(fits.without.summary.success);
  REQUIRE(fits.with.summary.success);
  fits.worst_without = WorstZ(fits.without, c.truth, &fits.which_without);
  return fits;
}

// Only the standard errors differ between the two fits: the same values, and the parameter
// `widened` (when named) has an error more than `factor` times the one it had without.
void CheckSameMinimum(const WithAndWithout& fits, const std::string& widened = "",
                      double factor = 1.0) {
  REQUIRE(fits.with.parameters.size() == fits.without.parameters.size());
  for (size_t i = 0; i < fits.with.parameters.size(); ++i) {
    const ParameterEstimate& with = fits.with.parameters[i];
    const ParameterEstimate& without = fits.without.parameters[i];
    CHECK(with.value == without.value);
    if (with.name == widened) CHECK(with.standard_error > factor * without.standard_error);
  }
}

// A random line fitted without any profile followed (profile_relax_widening 0; nor walked inward
// from a bound it is near, bound_walk_se 0, whose held points can widen the same errors) and with
// the defaults: the first `ok` more than 5 SE off, the second within 3 SE.
WithAndWithout CheckFollowedIntoThreeSe(const RandomLineCase& c) {
  auto fits = FitWithAndWithout(c, [](FitOptions* o) {
    o->profile_relax_widening = 0.0;
    o->bound_walk_se = 0.0;
  });
  INFO("not followed: worst " << fits.which_without << " at " << fits.worst_without << " SE");
  CHECK(fits.worst_without > 5.0);
  CHECK(fits.without.summary.verdict == "ok");
  std::string which;
  const double worst = WorstZ(fits.with, c.truth, &which);
  INFO("followed: worst " << which << " at " << worst << " SE");
  CHECK(worst < 3.0);
  return fits;
}

// The fit without a check (FitWithAndWithout) was a silent wrong answer, `ok` with `name` more
// than 5 SE from the truth; the one with the defaults ends within 3 SE.
void CheckSilentWrongMended(const RandomLineCase& c, const WithAndWithout& fits,
                            const std::string& name) {
  INFO("without: worst " << fits.which_without << " at " << fits.worst_without << " SE");
  CHECK(fits.worst_without > 5.0);
  CHECK(fits.which_without == name);
  CHECK(fits.without.summary.verdict == "ok");
  std::string which;
  const double worst = WorstZ(fits.with, c.truth, &which);
  INFO("with: " << fits.with.summary.verdict << ", worst " << which << " at " << worst << " SE");
  CHECK(worst < 3.0);
}

Oscillogram Rounded(Oscillogram record, int digits) {
  for (auto& column : record.values) {
    for (double& v : column) {
      std::ostringstream text;
      text << std::setprecision(digits) << v;
      v = std::stod(text.str());
    }
  }
  return record;
}

}  // namespace

TEST_CASE("three-mass line: every seed ends within 3 SE of the truth or says it is not sure") {
  const driveline::Scene truth = ThreeMassTruth();
  const driveline::Scene prior = ThreeMassPrior();
  int ok = 0;
  for (unsigned long seed = 1; seed <= 10; ++seed) {
    const Oscillogram record = ThreeMassRecord(truth, seed);
    const FitResult fit = Fit(prior, record, ThreeMassConfig(prior, record), FitOptions{});
    REQUIRE(fit.summary.success);
    std::string which;
    const double worst = WorstZ(fit, truth, &which);
    INFO("seed " << seed << ": verdict " << fit.summary.verdict << ", worst " << which << " at "
                 << worst << " SE");
    CHECK((worst <= 3.0 || fit.summary.verdict != "ok"));
    if (fit.summary.verdict == "ok") ++ok;
  }
  // A tool that doubts everything helps no one.
  CHECK(ok >= 9);
}

TEST_CASE("three-mass line: the record printed with 10 digits moves no parameter by 0.1 SE") {
  const driveline::Scene truth = ThreeMassTruth();
  const driveline::Scene prior = ThreeMassPrior();
  for (unsigned long seed = 1; seed <= 3; ++seed) {
    const Oscillogram record = ThreeMassRecord(truth, seed);
    const FitConfig config = ThreeMassConfig(prior, record);
    const FitResult full = Fit(prior, record, config, FitOptions{});
    const FitResult printed = Fit(prior, Rounded(record, 10), config, FitOptions{});
    REQUIRE(full.summary.success);
    REQUIRE(printed.summary.success);
    for (size_t i = 0; i < full.parameters.size(); ++i) {
      const auto& a = full.parameters[i];
      INFO("seed " << seed << ": " << a.name << " " << a.value << " vs "
                   << printed.parameters[i].value << ", SE " << a.standard_error);
      CHECK(std::abs(printed.parameters[i].value - a.value) <= 0.1 * a.standard_error);
    }
  }
}

TEST_CASE("random lines: a fixed sample of 20 seeds ends within 3 SE or not ok") {
  int ok = 0;
  for (unsigned long seed = 1001; seed <= 1020; ++seed) {
    const RandomLineCase c = MakeRandomLineCase(seed);
    const FitResult fit = Fit(c.prior, c.record, c.config, FitOptions{});
    REQUIRE(fit.summary.success);
    std::string which;
    const double worst = WorstZ(fit, c.truth, &which);
    INFO("seed " << seed << " (" << c.description << "): verdict " << fit.summary.verdict
                 << ", worst " << which << " at " << worst << " SE");
    CHECK((worst <= 3.0 || fit.summary.verdict != "ok"));
    if (fit.summary.verdict == "ok") ++ok;
  }
  CHECK(ok >= 18);
}

TEST_CASE("verdict ok: a speed-controlled drive that takes up the load slowly") {
  // Random line 107 (a 713 kg·m² motor, a 33 200 kg·m² roll) with a 12 Hz speed-PI drive on the
  // motor: the spindle torque still rises 0.25 s after the bite and reaches a tenth of its peak
  // only 41 ms after it. Its noise is measured before the response all the same, so the
  // residual is the noise and the fit is ok. (Measured up to 80 % of that tenth, the noise came
  // out 1.29 times too large and correlated, and the verdict was misfit.)
  const RandomLineCase c = MakeRandomLineCase(107, RandomLineVariant::kDrive);
  const FitResult fit = Fit(c.prior, c.record, c.config, FitOptions{});
  REQUIRE(fit.summary.success);
  std::string which;
  const double worst = WorstZ(fit, c.truth, &which);
  INFO(c.description << ": verdict " << fit.summary.verdict << ", worst " << which << " at "
                     << worst << " SE");
  CHECK(fit.summary.verdict == "ok");
  CHECK(worst <= 3.0);
  const auto& y = c.record.values[0];
  double peak = 0.0;
  for (const double v : y) peak = std::max(peak, std::abs(v - y[0]));
  const double sigma = c.record_spec.defects.noise_fraction * peak;
  CHECK(fit.channels[0].noise == Approx(sigma).epsilon(0.15));
  CHECK(fit.channels[0].whiteness_z < 3.0);
}

// A silent wrong answer without some of the gap kicks (`fits.without`: `ok`, more than 5 SE
// off) that the defaults' kicks take into the truth's valley, at least `drop` lower: only a kick
// reached it, so the starts may have missed a lower one still (`not_converged`).
void CheckKickedIntoTruthsValley(const RandomLineCase& c, const WithAndWithout& fits, double drop) {
  INFO("fewer kicks: " << fits.without.summary.verdict << ", worst " << fits.which_without << " at "
                       << fits.worst_without << " SE");
  CHECK(fits.worst_without > 5.0);
  CHECK(fits.without.summary.verdict == "ok");
  std::string which;
  const double worst = WorstZ(fits.with, c.truth, &which);
  INFO("kicked: " << fits.with.summary.verdict << ", worst " << which << " at " << worst << " SE");
  CHECK(worst < 3.0);
  CHECK(fits.with.summary.cost < fits.without.summary.cost - drop);
  CHECK(fits.with.summary.verdict == "not_converged");
  CHECK(Says(fits.with, "gap kick"));
}

// Random line 393 with a prior three times off (5 masses, two channels, gaps of 18.1 and 16.9
// mrad): every start, hop and walk ends in a valley whose motor-coupling gap is 1.7 % too wide,
// χ² 153 above the truth's, 8 SE off and ok. Held 2 % wider, the rest refitted, that gap costs
// more than the minimum; kicked 2 % wider and released, the fit falls into the truth's valley.
TEST_CASE("verdict not_converged: a gap kicked into the next valley of its impact timing") {
  const RandomLineCase c = MakeRandomLineCase(393, RandomLineVariant::kWidePrior);
  CheckKickedIntoTruthsValley(c, FitWithAndWithout(c, [](FitOptions* o) { o->gap_kick = 0.0; }),
                              40.0);
}

// Random line 8395 (5 masses, two channels, gaps of 7.4 and 8.6 mrad; first run of 8201–8400):
// one start of 12 ends in a valley where the motor coupling's gap is 3.9 % too wide, χ² 8 above
// the truth's, with its damping 22 SE off and an unobserved spindle's 14 SE off: `ok`. The 2 %
// kicks come back to it; kicked 4 % narrower, the fit falls into the truth's valley.
TEST_CASE("verdict not_converged: a gap kicked two valleys of its impact timing away") {
  const RandomLineCase c = MakeRandomLineCase(8395);
  CheckKickedIntoTruthsValley(
      c, FitWithAndWithout(c, [](FitOptions* o) { o->gap_kick_levels = 1; }), 3.0);
}

// Random line 384 under the no_pull law (five masses, gaps of 12.4 and 3.9 mrad, one channel):
// the damping's jump at each impact makes the misfit a staircase on the scale of the noise, and
// Levenberg–Marquardt stops on a step of it. A probe of the standard errors' profile check lies
// lower. The fit used to stop there, not_converged; it now goes on from that probe (as from an
// axis probe in the search) and ends in the minimum below, where no probe is lower. Since
// 2026-11-29 the search's walk inward from a bound that a parameter is near reaches that minimum
// first; it is off in both fits here, so that the restart is what is tested.
TEST_CASE("verdict ok: a profile probe below the minimum is gone on from") {
  const RandomLineCase c = MakeRandomLineCase(384, RandomLineVariant::kNoPull);
  FitOptions gone_on;
  gone_on.bound_walk_se = 0.0;
  const auto fits = FitWithAndWithout(
      c, [](FitOptions* o) { o->profile_restarts = 0; }, gone_on);
  INFO("without restarts: " << fits.without.summary.verdict << ", cost "
                            << fits.without.summary.cost << ", worst " << fits.which_without
                            << " at " << fits.worst_without << " SE");
  CHECK(fits.without.summary.verdict == "not_converged");
  CHECK(Says(fits.without, "found a lower cost"));
  std::string which;
  const double worst = WorstZ(fits.with, c.truth, &which);
  INFO("gone on: " << fits.with.summary.verdict << ", cost " << fits.with.summary.cost << ", worst "
                   << which << " at " << worst << " SE");
  CHECK(fits.with.summary.cost < fits.without.summary.cost);
  CHECK_FALSE(Says(fits.with, "found a lower cost"));
  CHECK(fits.with.summary.verdict == "ok");
  CHECK(worst < 3.0);
}

TEST_CASE("verdict misfit: a scene with the wrong spindle stiffness cannot explain the record") {
  const Oscillogram record = Mill5Record(0.01, 12, 0.0, 3);
  auto scene = Mill5Scene();
  FitConfig config = Mill5Config(record, &scene);
  // Not free here, and 40 % off: the spindle's mode is in the wrong place.
  std::erase_if(config.free, [](const FreeParameter& p) {
    return p.parameter.name == "upper_spindle.stiffness";
  });
  driveline::ParseSceneParameter(scene, "upper_spindle.stiffness", "test").Set(0.7e7, &scene);
  const FitResult fit = Fit(scene, record, config, FitOptions{});
  REQUIRE(fit.summary.success);
  for (const auto& w : fit.summary.warnings) UNSCOPED_INFO(w);
  CHECK(fit.summary.verdict == "misfit");
  bool named = false;
  for (const auto& w : fit.summary.warnings) named = named || w.find("upper_spindle") != w.npos;
  CHECK(named);
}

TEST_CASE("verdict not_converged: an iteration limit of 1") {
  const Oscillogram record = Mill5Record(0.01, 12, 0.0, 3);
  auto scene = Mill5Scene();
  const FitConfig config = Mill5Config(record, &scene);
  FitOptions options;
  options.max_iterations = 1;
  options.profile_restarts = 0;
  const FitResult fit = Fit(scene, record, config, options);
  REQUIRE(fit.summary.success);
  CHECK(fit.summary.verdict == "not_converged");
  REQUIRE_FALSE(fit.summary.warnings.empty());
  CHECK_THAT(fit.summary.warnings.front(), Contains("did not converge"));
}

// Random line 393 (two 17-18 mrad gaps): every start ends in a valley 18 SE from the truth, a
// basin hop finds a lower one that is still wrong (the truth's is lower again by a χ² of 200),
// and no residual test can tell: the noise estimate's own uncertainty hides a 10 % excess. It
// used to be called ok.
TEST_CASE("verdict not_converged: a best minimum that only a basin hop reached") {
  const RandomLineCase c = MakeRandomLineCase(393);
  const DefaultFit line(c);
  const FitResult& fit = line.fit;
  INFO("worst " << line.which << " at " << line.worst << " SE");
  CHECK(line.worst > 5.0);  // the answer is wrong: the verdict is what keeps it from passing as ok
  CHECK(fit.summary.verdict == "not_converged");
  CHECK(Says(fit, "basin hop"));
  // The fit still reports what it has.
  CHECK(fit.summary.cost > 0.0);
  CHECK(fit.parameters.size() == c.config.free.size());
}

// Random line 34 under the no_pull law (six masses, three 1.0-1.5 mrad gaps): the damping's
// jump at each impact makes the misfit a staircase, and every start's fit stops on a step of it,
// χ² 7.8 above the minimum a basin hop then reaches. The starts' fits lie 0.6 standard errors
// from that minimum (the Mahalanobis length under its linearisation): they found its valley,
// only not its floor. It used to be called not_converged, a false alarm within 3 SE of the truth.
// Seed 393 above is the other side: its starts' fits lie within 3 SE of the hop's minimum in
// every parameter one by one, but 9 SE along a correlated direction, and stay flagged.
TEST_CASE("verdict ok: starts that stopped on the rough floor of the best minimum's valley") {
  const RandomLineCase c = MakeRandomLineCase(34, RandomLineVariant::kNoPull);
  const DefaultFit line(c);
  const FitResult& fit = line.fit;
  INFO("verdict " << fit.summary.verdict << ", worst " << line.which << " at " << line.worst
                  << " SE");
  // The premise: only a hop (start −1) reached the best minimum, χ² more than 4 below every
  // start's fit.
  double best = std::numeric_limits<double>::infinity(), best_start = best;
  int best_from = 0;
  for (const auto& minimum : fit.minima) {
    if (minimum.cost < best) {
      best = minimum.cost;
      best_from = minimum.start;
    }
    if (minimum.start >= 0) best_start = std::min(best_start, minimum.cost);
  }
  REQUIRE(best_from < 0);
  REQUIRE(2.0 * (best_start - best) / (fit.summary.noise_scale * fit.summary.noise_scale) > 4.0);
  CHECK(fit.summary.verdict == "ok");
  CHECK_FALSE(Says(fit, "reached only by"));
  CHECK(Says(fit, "stopped in the best minimum's valley"));  // still said, as a doubt
  CHECK(line.worst < 3.0);
}

// Random line 12024 (6 masses in a chain, two gaps, three dampings the record hardly sees; first
// seen in the first run of seeds 12001–12200, `not_converged` under six of the nine variants):
// at the best minimum Levenberg–Marquardt ran into its 100 iterations. 300 more lowered χ² by
// 0.03 and moved no estimate by 0.01 of its standard error: it creeps along the floor, where the
// Gauss–Newton step promises more than the valley gives. It was called not_converged, a false
// alarm within 3 SE of the truth.
TEST_CASE("verdict ok: Levenberg-Marquardt creeping along the floor ends there") {
  const RandomLineCase c = MakeRandomLineCase(12024);
  const auto fits = FitWithAndWithout(c, [](FitOptions* o) { o->creep_iterations = 0; });
  CHECK(fits.without.summary.verdict == "not_converged");
  CHECK(Says(fits.without, "Maximum number of iterations"));
  CHECK(fits.worst_without < 3.0);
  std::string which;
  const double worst = WorstZ(fits.with, c.truth, &which);
  INFO("with: " << fits.with.summary.verdict << ", worst " << which << " at " << worst << " SE");
  CHECK(fits.with.summary.verdict == "ok");
  CHECK(worst < 3.0);
  CHECK(fits.with.summary.simulations < fits.without.summary.simulations);
  // The same minimum, within a tenth of a standard error, and χ² within 0.1.
  REQUIRE(fits.with.parameters.size() == fits.without.parameters.size());
  for (size_t i = 0; i < fits.with.parameters.size(); ++i) {
    const ParameterEstimate& with = fits.with.parameters[i];
    INFO(with.name);
    CHECK(std::abs(with.value - fits.without.parameters[i].value) < 0.1 * with.standard_error);
  }
  const double scale2 = fits.with.summary.noise_scale * fits.with.summary.noise_scale;
  CHECK(2.0 * std::abs(fits.with.summary.cost - fits.without.summary.cost) / scale2 < 0.1);
}

// Random line 12121 (6 masses in a random tree): with the creep stop alone, a straight profile
// probe 0.006 (½ χ²) below the crept minimum restarted the refinement, which crept and stopped as
// short, twice, and the fit ended not_converged ("found a lower cost") within 3 SE. A probe lower
// by no more than the creep stop's own slack (FloorCost) is on the minimum's floor.
TEST_CASE("verdict ok: a probe lower only by the creep stop's slack is not a lower point") {
  const DefaultFit line(MakeRandomLineCase(12121));
  INFO("verdict " << line.fit.summary.verdict << ", worst " << line.which << " at " << line.worst
                  << " SE");
  CHECK(line.fit.summary.verdict == "ok");
  CHECK_FALSE(Says(line.fit, "found a lower cost"));
  CHECK(line.worst < 3.0);
}

// Random line 555 (six masses, two 1.07 mrad gaps): the fit, from the truth too, ends 8.9
// linearised standard errors from the motor coupling's true backlash. Along the straight profile
// direction the misfit is quadratic out to 8 SE, so the straight probes see nothing; the truth
// lies in a valley that curves away from that line, where the profile with the other quantities
// refitted rises by only χ² 5.6 at 8 SE. Without the relaxed probes it was a silent wrong answer.
TEST_CASE("standard errors: a valley that curves away from the straight profile is followed") {
  const RandomLineCase c = MakeRandomLineCase(555);
  const auto fits = FitWithAndWithout(c, [](FitOptions* o) { o->profile_relax_widening = 0.0; });
  const FitResult& before = fits.without;
  const FitResult& fit = fits.with;
  INFO("straight probes only: worst " << fits.which_without << " at " << fits.worst_without
                                      << " SE");
  CHECK(fits.worst_without > 5.0);
  CHECK(fits.which_without == "motor_coupling_hub.backlash");
  std::string which;
  const double worst = WorstZ(fit, c.truth, &which);
  INFO("relaxed: worst " << which << " at " << worst << " SE");
  CHECK(worst < 3.0);
  // The search is the same: the same values, only the standard errors differ.
  REQUIRE(fit.parameters.size() == before.parameters.size());
  for (size_t i = 0; i < fit.parameters.size(); ++i) {
    CHECK(fit.parameters[i].value == before.parameters[i].value);
    if (fit.parameters[i].name == "motor_coupling_hub.backlash") {
      CHECK(fit.parameters[i].standard_error > 3.0 * before.parameters[i].standard_error);
    }
  }
  bool said = false;
  for (const auto& w : fit.summary.warnings) {
    said = said || (w.find("widened") != w.npos && w.find("motor_coupling_hub.backlash") != w.npos);
  }
  CHECK(said);
  CHECK(fit.summary.verdict == before.summary.verdict);
}

// Random line 765 (6 masses, three channels): the intermediate shaft's damping comes out at a
// quarter of the truth, 6.2 linearised standard errors off; the fit from the truth ends there too.
// Two standard errors along its straight profile direction the cost rises 60 to 160 times the
// prediction, and one Gauss–Newton step with the minimum's Jacobian cannot relax that; the
// profile followed with the damping held rises by only χ² 2 there.
// Random line 252 with its loads applied as steps (five masses, three gaps under 2 mrad, one
// channel): the two dampings either side of the gearbox trade against each other along a valley
// that is flat for a decade (the profile of the gearbox one rises only χ² 2.9, 4.7 and 5.8 at
// 2, 3 and 4 linearised SE, then falls to 5.1 at 6 SE). Relaxed at 2 SE the probe implies a
// standard error 1.15–1.25 times the linearised one; not followed, the fit was `ok` with both
// dampings 6 SE from the truth, whose χ² is only 7.6 above the minimum's. Until the relaxed probe
// at 4 SE (2026-11-29) it was followed only with the threshold at 1.15, not at 1.25; that probe
// now follows it at 1.25 too.
TEST_CASE(
    "standard errors: a profile a little flatter than its linearisation at 2 SE is followed") {
  const RandomLineCase c = MakeRandomLineCase(252, RandomLineVariant::kStepLoad);
  const auto fits = CheckFollowedIntoThreeSe(c);
  CHECK(fits.with.summary.verdict == "ok");
  CheckSameMinimum(fits);
  FitOptions coarser;
  coarser.profile_relax_widening = 1.25;
  const FitResult at_125 = Fit(c.prior, c.record, c.config, coarser);
  std::string which;
  const double worst_at_125 = WorstZ(at_125, c.truth, &which);
  INFO("followed above 1.25: worst " << which << " at " << worst_at_125 << " SE");
  CHECK(worst_at_125 < 3.0);
  // The motor-side damping ends 1.7 linearised SE below its upper bound: walked inward from it,
  // with no profile followed, the held points widen the two dampings' errors as far (2026-11-29).
  FitOptions walked_only;
  walked_only.profile_relax_widening = 0.0;
  const FitResult walked = Fit(c.prior, c.record, c.config, walked_only);
  const double worst_walked = WorstZ(walked, c.truth, &which);
  INFO("walked inward, not followed: worst " << which << " at " << worst_walked << " SE");
  CHECK(worst_walked < 3.0);
}

TEST_CASE("standard errors: a profile whose valley bends sharply is followed") {
  const RandomLineCase c = MakeRandomLineCase(765);
  const auto fits = FitWithAndWithout(c, [](FitOptions* o) { o->profile_bend_ratio = 0.0; });
  INFO("not followed: worst " << fits.which_without << " at " << fits.worst_without << " SE");
  CHECK(fits.worst_without > 5.0);
  CHECK(fits.which_without == "intermediate_shaft_pinion_stand.damping");
  std::string which;
  const double worst = WorstZ(fits.with, c.truth, &which);
  INFO("followed: worst " << which << " at " << worst << " SE");
  CHECK(worst < 3.0);
  CheckSameMinimum(fits);
}

// Random line 712 (6 masses, two channels): the motor coupling's and the next shaft's dampings
// trade off along a banana-shaped valley. The fit from the truth ends at the same minimum, the
// truth at χ² 9 above it, yet the linearised errors put it 5.2 and 5.1 standard errors away.
// Their straight probes rise 14 to 28 times the prediction, too little to count as a sharp bend
// at 100 times; the second damping's profile held at 8 standard errors rises by only χ² 9.
TEST_CASE("standard errors: a profile that bends 10 to 30 times the prediction is followed") {
  const RandomLineCase c = MakeRandomLineCase(712);
  const auto fits = FitWithAndWithout(c, [](FitOptions* o) { o->profile_bend_ratio = 100.0; });
  INFO("followed only past 100: worst " << fits.which_without << " at " << fits.worst_without
                                        << " SE");
  CHECK(fits.worst_without > 5.0);
  CHECK(fits.without.summary.verdict == "ok");  // the silent wrong answer it was
  std::string which;
  const double worst = WorstZ(fits.with, c.truth, &which);
  INFO("followed past 10: worst " << which << " at " << worst << " SE");
  CHECK(worst < 4.0);
  CheckSameMinimum(fits, "coupling_hub_gearbox.damping", 1.5);
}

// Random line 8831 under no_pull (3 masses, two channels, a 1.8 mrad gap next to the motor; first
// seen in the first run of seeds 8801–9000): the fit from the truth ends at the same minimum,
// the gap 5.6 linearised standard errors below the truth. Held and refitted, its profile rises
// χ² 3.3 at 2 standard errors, as the linearisation predicts, then flattens: 3.2 at 2.8, 4.6 at
// 4.5, 6.7 at the truth. The relaxed probe at 4 standard errors sees the shoulder, and the
// profile followed there widens the gap's error about twice.
TEST_CASE("standard errors: a profile quadratic to 2 SE that flattens beyond is followed") {
  const auto fits = CheckFollowedIntoThreeSe(MakeRandomLineCase(8831, RandomLineVariant::kNoPull));
  CheckSameMinimum(fits, "motor_gearbox.backlash", 1.5);
}

// Random line 9326 under a drive loop (5 masses, two channels near the motor, three gaps; first
// seen in the first run of seeds 9201–9400): the fit from the truth ends at the same minimum, the
// upper spindle's gap at 2.3 mrad, 12 linearised standard errors below the truth's 7.0. Held and
// refitted, the gap's profile is quadratic past 2 and 4 standard errors, rises to a wall of χ² 17
// at 5 mrad and falls to a second valley at the truth, χ² 5 above the minimum: no probe near the
// minimum sees past the wall. The gap held across its range does.
TEST_CASE("standard errors: a gap's second valley behind a wall is found across its range") {
  const RandomLineCase c = MakeRandomLineCase(9326, RandomLineVariant::kDrive);
  const auto fits = FitWithAndWithout(c, [](FitOptions* o) { o->gap_profile_points = 0; });
  CheckSilentWrongMended(c, fits, "upper_spindle.backlash");
  CheckSameMinimum(fits, "upper_spindle.backlash", 3.0);
  CHECK(Says(fits.with, "upper_spindle.backlash"));
}

// Random line 9661 with a fast recorder low-pass (6 masses, the stand split at its pinion stand,
// three gaps; first seen in the first run of seeds 9601–9800): the search ends, after the second
// search's 12 starts, with the gear-to-pinion-stand damping 1.4e-5 of its log range above its
// lower bound, so not at it, its error 0.2 of the range, and says `ok` 10 linearised standard
// errors below the truth. Its profile check could probe only inward, where the followed point
// stopped where it started; the truth's valley, χ² 21 lower, lies at half the range. Walked
// inward from the bound it nearly touches, the search reaches that valley.
// The creep stop (2026-12-06) moved the search's path: with it, the fit without the walk reaches
// the truth's valley too (`not_converged`, 1.4 SE off). The walk is checked on the path where it
// was found, the creep stop off in both fits; with the defaults the fit ends within 3 SE.
TEST_CASE("the search: a parameter within 2 standard errors of a bound is walked inward from it") {
  const RandomLineCase c = MakeRandomLineCase(9661, RandomLineVariant::kFastLowpass);
  FitOptions no_creep;
  no_creep.creep_iterations = 0;
  const auto fits = FitWithAndWithout(
      c, [](FitOptions* o) { o->bound_walk_se = 0.0; }, no_creep);
  CheckSilentWrongMended(c, fits, "gearbox_pinion_stand.damping");
  CHECK(fits.with.summary.cost < fits.without.summary.cost - 5.0);
  const DefaultFit line(c);
  INFO("defaults: " << line.fit.summary.verdict << ", worst " << line.which << " at " << line.worst
                    << " SE");
  CHECK(line.worst < 3.0);
  FitOptions options;
  options.bound_walk_se = -1.0;
  CHECK_THROWS_WITH(options.Validate(), Catch::Contains("bound_walk_se"));
  options.bound_walk_se = 17.0;
  CHECK_THROWS_WITH(options.Validate(), Catch::Contains("bound_walk_se"));
}

// Random line 958 (3 masses, no gap, one channel; a seed the defaults were not tuned on): every
// start ends with the spindle's damping pressed against its lower bound, 7.4e3 where the truth
// is 9.6e4, at a χ² only 0.6 above the minimum near the truth. Its linearised standard error,
// 1.5e4, is small against the bound width 7.3e5 but twice the value: on the log scale the
// damping is fitted on, it spans 0.4 of the two decades. The motor-side damping, which trades
// against it, came out 6 linearised standard errors off. Held along the spindle damping's
// followed profile, or walked inward from its bound, the others refitted, the χ² stays flat
// while the motor damping moves back towards the truth; those points widen its error.
TEST_CASE("standard errors: points held on walks widen every parameter they move") {
  const RandomLineCase c = MakeRandomLineCase(958);
  const auto fits = FitWithAndWithout(c, [](FitOptions* o) {
    o->curved_valley_ratio = 0.0;     // no walk from a bound
    o->profile_relax_widening = 0.0;  // no followed profile
  });
  CheckSilentWrongMended(c, fits, "motor_gearbox.damping");
  // The walk finds nothing lower: only errors widen.
  CheckSameMinimum(fits, "motor_gearbox.damping", 2.0);
  for (size_t i = 0; i < fits.with.parameters.size(); ++i) {
    if (fits.with.parameters[i].name != "spindle.damping") continue;
    CHECK(fits.with.parameters[i].at_bound);
    // Not identifiable either way: its standard error spans most of its log range.
    CHECK_FALSE(fits.without.parameters[i].identifiable);
    CHECK(fits.without.parameters[i].why_not.find("log scale") != std::string::npos);
  }
}

// Random line 2084 (6 masses, two channels, three gaps; a seed the defaults were not tuned on):
// the motor coupling's damping lies on a profile 112 times flatter than its linearisation at
// 2 standard errors, and its error widens 10.6 times. Its 10.7 mrad gap, correlated with it at
// 0.94, came out at 2.1 ± 1.05 mrad, 8 standard errors off, and `ok`: the fit from the truth
// ends there too. The gap's spread given the damping is kept, so it widens with the damping.
TEST_CASE("standard errors: what is correlated with a widened parameter widens with it") {
  const RandomLineCase c = MakeRandomLineCase(2084);
  const DefaultFit line(c);
  const FitResult& fit = line.fit;
  INFO(fit.summary.verdict << ", worst " << line.which << " at " << line.worst << " SE");
  CHECK(line.worst < 3.0);
  CHECK(Says(fit, "motor_hub1.backlash x"));  // the widening it inherits is reported
  CheckWithinStandardErrors(fit, c.truth, "motor_hub1.backlash", 3.0);
}

TEST_CASE("standard errors: parameters correlated with one not identifiable are checked too") {
  // Random line 7872: gearbox_pinion_stand.damping, not identifiable, sits at its lower bound with
  // a variance of several times its range, correlated with motor_gearbox.damping and .backlash.
  // Their profile directions took it out of its bounds at ±2 SE, so both probes were dropped and
  // neither parameter was checked: `ok` with motor_gearbox.damping 16 820 ± 4310 against a truth
  // of 45 344 (−6.62 SE), where the held profile is flat from 3 to 5 SE. That parameter is held at
  // its bound in those probes now: the damping's error widens 2.3 times (−3.06 SE).
  const RandomLineCase c = MakeRandomLineCase(7872);
  const DefaultFit line(c);
  const FitResult& fit = line.fit;
  INFO(fit.summary.verdict << ", worst " << line.which << " at " << line.worst << " SE");
  CHECK((line.worst < 5.0 || fit.summary.verdict != "ok"));
  CheckWithinStandardErrors(fit, c.truth, "motor_gearbox.damping", 4.0);
}

TEST_CASE("search: a curved valley is followed where its direction meets another's bound") {
  // Random line 7832 with a fitted stiffness (6 masses, three gaps, two channels): every start
  // ended in valleys χ² 300 and more above the truth's, the best `misfit` with the fitted
  // stiffness 17 SE off. The probe of the curved-valley test moved another parameter past its
  // bound and was dropped, so that valley was never followed. That parameter is held at the
  // bound now (as in the standard errors' check): the walk reaches the truth's valley, and the
  // starts having missed it, the verdict says so.
  const RandomLineCase c = MakeRandomLineCase(7832, RandomLineVariant::kStiffness);
  const DefaultFit line(c);
  const FitResult& fit = line.fit;
  INFO(fit.summary.verdict << ", cost " << fit.summary.cost << ", worst " << line.which << " at "
                           << line.worst << " SE");
  CHECK(line.worst < 3.0);
  CHECK(fit.summary.verdict == "not_converged");
  CHECK(fit.summary.starts_at_best == 0);
}

namespace {

// A random line fitted with one search and with the default, which runs the search again when no
// more than half the starts reach the best minimum (4 times the scan, twice the starts): checks
// the trigger and that the second search ends at a minimum no worse, within 3 SE.
WithAndWithout CheckSearchedAgain(const RandomLineCase& c) {
  auto fits = FitWithAndWithout(c, [](FitOptions* o) { o->escalation_factor = 1; });
  const FitResult& once = fits.without;
  const FitResult& fit = fits.with;
  INFO("one search: " << once.summary.verdict << ", cost " << once.summary.cost << ", "
                      << once.summary.starts_at_best << "/" << once.summary.starts
                      << " starts at the best, worst " << fits.which_without << " at "
                      << fits.worst_without << " SE");
  CHECK(2 * once.summary.starts_at_best <= once.summary.starts);  // what runs the search again
  CHECK_FALSE(once.summary.escalated);
  std::string which;
  const double worst = WorstZ(fit, c.truth, &which);
  INFO("searched twice: " << fit.summary.verdict << ", cost " << fit.summary.cost << ", worst "
                          << which << " at " << worst << " SE");
  CHECK(fit.summary.escalated);
  CHECK(fit.summary.starts == 3 * once.summary.starts);
  CHECK(fit.summary.cost <= once.summary.cost + 1e-6);  // never a worse minimum
  CHECK(worst < 3.0);
  return fits;
}

}  // namespace

// The second search was built for random line 378 (6 masses, one channel, three gaps), whose
// four starts ended in four valleys χ² 95 to 11000 apart: one search ended χ² 95 above the truth's
// minimum, `ok` with a damping 12 standard errors off, and the second found the truth's. Which
// valley a start ends in moves with roundoff: since the limited law's corner takes the
// spring-damper piece (2026-11-28) line 378's single search reaches the truth's valley, and no line
// of seeds 100–699 needs the second search to be right (scanned with it off). Line 413 (6 masses,
// three gaps) still scatters its starts: 1 of 4 at the best.
TEST_CASE("verdict ok: starts scattered over many valleys run the search again") {
  const auto fits = CheckSearchedAgain(MakeRandomLineCase(413));
  CHECK(fits.with.summary.verdict == "ok");
}

// Half the starts are not a majority. Random line 8708 with a wide prior (6 masses, five gaps,
// one channel): 2 of 4 starts end in one valley, χ² 34 above the truth's minimum with a damping
// 11.8 SE off; the residual is 12 % above the noise, which the misfit test cannot tell from
// noise. Searched again, the truth's valley is the best.
TEST_CASE("verdict ok: a wrong valley that half the starts reach runs the search again") {
  const auto fits = CheckSearchedAgain(MakeRandomLineCase(8708, RandomLineVariant::kWidePrior));
  const FitResult& once = fits.without;
  CHECK(2 * once.summary.starts_at_best == once.summary.starts);
  CHECK(once.summary.verdict == "ok");
  CHECK(fits.worst_without > 5.0);
  CHECK(2.0 * (once.summary.cost - fits.with.summary.cost) > 20.0);
  CHECK(fits.with.summary.verdict == "ok");
}

// Random line 526 (3 masses, one channel, a 17.7 mrad gap): every start and every basin hop
// reach one minimum, 25 SE off in the lower spindle's damping, whose χ² is 106 above the truth's;
// the noise from 116 quiet samples is too uncertain for the misfit test to see it. Two standard
// errors along the straight profile directions the cost rises hundreds of times the prediction:
// the valley bends sharply. Followed with one parameter held, it leads down to the truth's.
TEST_CASE("verdict not_converged: a lower valley found along a sharply curved one") {
  const RandomLineCase c = MakeRandomLineCase(526);
  // The gap kicks reach that valley too (from the 17.7 mrad gap set 2 % wider): off here.
  const auto fits = FitWithAndWithout(c, [](FitOptions* o) {
    o->curved_valley_ratio = 0.0;
    o->gap_kick = 0.0;
  });
  const FitResult& before = fits.without;
  const FitResult& fit = fits.with;
  INFO("not followed: " << before.summary.verdict << ", worst " << fits.which_without << " at "
                        << fits.worst_without << " SE");
  CHECK(fits.worst_without > 5.0);
  std::string which;
  CHECK(before.summary.verdict == "ok");  // the silent wrong answer it was
  const double worst = WorstZ(fit, c.truth, &which);
  INFO("followed: " << fit.summary.verdict << ", worst " << which << " at " << worst << " SE");
  CHECK(worst < 3.0);
  CHECK(fit.summary.cost < before.summary.cost - 40.0);  // χ² about 106 lower
  // Only the followed profile reached it: the starts may have missed a lower one still.
  CHECK(fit.summary.verdict == "not_converged");
  bool said = false;
  for (const auto& w : fit.summary.warnings) said = said || w.find("followed valley") != w.npos;
  CHECK(said);
}

TEST_CASE("verdict not_converged: a gap left open at a minimum is held below where it closes") {
  // Seed 91 under the fast-lowpass variant: the search with its seeds moved by 7 (or 37) ended
  // every start where the lower spindle's gap (truth 15.4 mrad) never closes and the bite time,
  // 22 SE off, makes up for it, χ² about 320 above the truth's valley, which lies just below the
  // smallest gap that stays open. Here that state is the one start (those values, the gap at 35
  // to 60 mrad, where the cost does not depend on it at all), the scan off. Which of those
  // starts a fit without the held gap leaves by another way (a probe, a hop) is roundoff's
  // choice (3 of 18 nearby starts); that most do not is the premise.
  RandomLineCase c = MakeRandomLineCase(91, RandomLineVariant::kFastLowpass);
  c.config.scan_points = 0;
  c.config.starts = 1;
  std::map<std::string, double> wrong_valley = {
      {"motor_gearbox.damping", 149443.0}, {"motor_gearbox.backlash", 0.00935566},
      {"upper_spindle.damping", 240331.0}, {"lower_spindle.damping", 304548.0},
      {"lower_spindle.backlash", 0.0},     {"bite_time", 0.0409976}};
  FitOptions not_held;
  not_held.open_gap_points = 0;
  int wrong_before = 0;
  for (const double gap : {0.035, 0.04, 0.05, 0.06}) {
    wrong_valley["lower_spindle.backlash"] = gap;
    for (auto& free : c.config.free) free.start = wrong_valley.at(free.parameter.name);
    const FitResult before = Fit(c.prior, c.record, c.config, not_held);
    const FitResult fit = Fit(c.prior, c.record, c.config, FitOptions{});
    REQUIRE(before.summary.success);
    REQUIRE(fit.summary.success);
    std::string which_before, which;
    const double worst_before = WorstZ(before, c.truth, &which_before);
    const double worst = WorstZ(fit, c.truth, &which);
    INFO("gap start " << gap);
    INFO("not held: " << before.summary.verdict << ", cost " << before.summary.cost << ", worst "
                      << which_before << " at " << worst_before << " SE");
    INFO("held: " << fit.summary.verdict << ", cost " << fit.summary.cost << ", worst " << which
                  << " at " << worst << " SE");
    CHECK(worst < 3.0);
    if (worst_before > 5.0) {
      ++wrong_before;
      CHECK(before.summary.verdict == "ok");  // the silent wrong answer it was
      CHECK(fit.summary.cost < before.summary.cost - 40.0);
      // Only the held gap reached it: the starts may have missed a lower valley still.
      CHECK(fit.summary.verdict == "not_converged");
    }
  }
  CHECK(wrong_before >= 2);
}

TEST_CASE("verdict ok: the bundled scene on its own noisy record") {
  const Oscillogram record = Mill5Record(0.01, 12, 0.0, 3);
  auto scene = Mill5Scene();
  FitConfig config = Mill5Config(record, &scene);
  config.scan_points = kDefaultScanPoints;
  config.starts = kDefaultStarts;
  const FitResult fit = Fit(scene, record, config, FitOptions{});
  REQUIRE(fit.summary.success);
  CHECK(fit.summary.verdict == "ok");
  CHECK(fit.summary.starts_at_best >= 1);
  CHECK(fit.summary.starts_at_best <= fit.summary.starts);
  // Fixed weights from the record's quiet stretch: the residual agrees with them.
  CHECK(fit.summary.noise_scale > 0.9);
  CHECK(fit.summary.noise_scale < 1.1);
}

TEST_CASE("verdict ambiguous: two spindles that only the motor shaft sees can swap their gaps") {
  // Two identical roll branches behind one pinion; the only channel is the motor shaft, which
  // sees the sum of the branches: gaps (a, b) and (b, a) give the same record.
  driveline::Scene truth;
  truth.name = "symmetric stand";
  truth.duration_s = 0.3;
  truth.sample_rate_Hz = 2000.0;
  truth.initial_speed_rad_per_s = 10.0;
  truth.masses = {{"motor", 12000.0}, {"pinion", 3000.0}, {"roll_a", 1000.0}, {"roll_b", 1000.0}};
  using driveline::testing::MakeLink;
  truth.links = {MakeLink("motor_shaft", 0, 1, 2e8, 4e4, 0.0),
                 MakeLink("spindle_a", 1, 2, 1e7, 4000.0, 0.010),
                 MakeLink("spindle_b", 1, 3, 1e7, 4000.0, 0.025)};
  for (const int roll : {2, 3}) {
    driveline::TorqueSource load;
    load.name = "load";
    load.mass = roll;
    load.times_s = {0.05, 0.06};
    load.values_Nm = {0.0, -100000.0};
    truth.torques.push_back(load);
  }
  driveline::ValidateScene(truth);
  RecordSpec spec;
  spec.defects.sample_rate_Hz = 2000.0;
  spec.defects.noise_fraction = 0.01;
  spec.defects.bits = 12;
  spec.defects.seed = 5;
  spec.channels = {{"motor_shaft", 0, 1.0, 0.0}};
  const Oscillogram record = GenerateRecord(truth, spec);
  driveline::Scene prior = truth;
  prior.links[1].backlash_rad = prior.links[2].backlash_rad = 0.017;
  FitConfig config;
  for (const std::string name : {"spindle_a.backlash", "spindle_b.backlash"}) {
    FreeParameter p;
    p.parameter = driveline::ParseSceneParameter(prior, name, "test");
    p.start = 0.017;
    p.lower = 0.004;
    p.upper = 0.04;
    p.scan = true;
    config.free.push_back(p);
  }
  ChannelSpec channel;
  channel.column = channel.link = "motor_shaft";
  channel.link_index = 0;
  config.channels = {channel};
  config.window_start_s = record.time_s.front();
  config.window_end_s = record.time_s.back();
  const FitResult fit = Fit(prior, record, config, FitOptions{});
  REQUIRE(fit.summary.success);
  INFO("a = " << fit.parameters[0].value << ", b = " << fit.parameters[1].value);
  CHECK(fit.summary.verdict == "ambiguous");
  CHECK(fit.summary.starts_at_best < fit.summary.starts);
}

TEST_CASE("degenerate records end in the verdict degenerate with the reason") {
  Oscillogram record = Mill5Record(0.01, 12, 0.0, 3);
  auto scene = Mill5Scene();
  const FitConfig config = Mill5Config(record, &scene);
  const auto expect_degenerate = [&](const Oscillogram& bad, const std::string& reason) {
    const FitResult fit = Fit(scene, bad, config, FitOptions{});
    REQUIRE(fit.summary.success);
    CHECK(fit.summary.verdict == "degenerate");
    REQUIRE_FALSE(fit.summary.warnings.empty());
    CHECK_THAT(fit.summary.warnings.front(), Contains(reason));
    CHECK(fit.channels.size() == config.channels.size());
  };
  SECTION("an all-zero channel (a dead gauge)") {
    for (double& v : record.values[1]) v = 0.0;
    expect_degenerate(record, "constant");
  }
  SECTION("a constant record") {
    for (auto& column : record.values) {
      for (double& v : column) v = 1234.5;
    }
    expect_degenerate(record, "constant");
  }
  SECTION("values of 1e300") {
    for (auto& column : record.values) {
      for (double& v : column) v = 1e300;
    }
    expect_degenerate(record, "not a torque");
  }
  SECTION("too few samples after the bite") {
    // The bite at 53.7 ms; keep 6 samples (3 ms) after it: fewer than the 13 fitted quantities.
    // Noise-free, so that the response's start is sharp.
    record = Mill5Record(0.0, 0, 0.0, 3);
    const auto [begin, end] = record.WindowRange(0.0, 0.0567);
    record.time_s.resize(end);
    for (auto& column : record.values) column.resize(end);
    auto short_scene = Mill5Scene();
    FitConfig short_config = config;
    short_config.window_end_s = record.time_s.back();
    const FitResult fit = Fit(short_scene, record, short_config, FitOptions{});
    REQUIRE(fit.summary.success);
    CHECK(fit.summary.verdict == "degenerate");
    REQUIRE_FALSE(fit.summary.warnings.empty());
    CHECK_THAT(fit.summary.warnings.back(), Contains("fewer than the"));
  }
}

TEST_CASE("identify on a dead channel exits 3 with every output written and no temporary file") {
  using namespace millkit::testing;
  ScratchDir dir;
  Oscillogram record = Mill5Record(0.01, 12, 800.0, 3);
  for (double& v : record.values[1]) v = 0.0;
  WriteText(dir / "dead.csv", FormatOscillogram(record));
  const auto result =
      RunMillkit("identify '" + SourcePath("datasets/scenes/mill5_bite.toml") + "' --data '" +
                 (dir / "dead.csv").string() + "' --config '" +
                 SourcePath("datasets/records/mill5_two_spindles.fit.toml") + "' --out '" +
                 (dir / "fit.json").string() + "' --plot '" + (dir / "fit.svg").string() + "'");
  INFO(result.stderr_text);
  CHECK(result.exit_code == 3);
  CHECK_THAT(result.stderr_text, Contains("verdict: degenerate"));
  const auto fit = nlohmann::json::parse(ReadText(dir / "fit.json"));
  CHECK(fit["verdict"] == "degenerate");
  CHECK(fit["success"] == false);
  CHECK(std::filesystem::exists(dir / "fit.svg"));
  for (const auto& entry : std::filesystem::directory_iterator(dir.path())) {
    INFO(entry.path());
    CHECK(entry.path().filename().string().find(".tmp") == std::string::npos);
  }
}

TEST_CASE("identify without a config on the bundled record says it is not sure and exits 3") {
  using namespace millkit::testing;
  ScratchDir dir;
  const auto result =
      RunMillkit("identify '" + SourcePath("datasets/scenes/mill5_bite.toml") + "' --data '" +
                 SourcePath("datasets/records/mill5_two_spindles.csv") + "' --out '" +
                 (dir / "fit.json").string() + "'");
  INFO(result.stderr_text);
  // The default config has no recorder filter: the model cannot explain the filtered record.
  CHECK(result.exit_code == 3);
  const auto fit = nlohmann::json::parse(ReadText(dir / "fit.json"));
  CHECK(fit["verdict"] != "ok");
  CHECK_FALSE(fit["warnings"].empty());
  CHECK(fit["success"] == false);
}

}  // namespace millkit::identify

namespace millkit::identify {

TEST_CASE("a gain held by its bounds is reported at the bound") {
  const Oscillogram record = Mill5Record(0.01, 12, 0.0, 3);  // true upper gain 1.03
  auto scene = Mill5Scene();
  FitConfig config = Mill5Config(record, &scene);
  config.channels[0].gain_lower = 0.9;
  config.channels[0].gain_upper = 1.0;
  const FitResult fit = Fit(scene, record, config, FitOptions{});
  REQUIRE(fit.summary.success);
  CHECK(fit.channels[0].gain == 1.0);
  CHECK(fit.channels[0].gain_at_bound);
  CHECK_FALSE(fit.channels[1].gain_at_bound);
  bool reported = false;
  for (const auto& w : fit.summary.warnings) reported = reported || w.find("gain_bounds") != w.npos;
  CHECK(reported);
}

TEST_CASE("gain bounds that exclude 1 are rejected naming the key") {
  using namespace millkit::testing;
  ScratchDir dir;
  const Oscillogram record = Mill5Record(0.0, 0, 0.0, 1);
  WriteText(dir / "fit.toml",
            "[[free]]\nname = \"upper_spindle.damping\"\nlower = 500.0\nupper = 30000.0\n"
            "[[channel]]\ncolumn = \"upper_spindle\"\ngain_bounds = [1.1, 2.0]\n");
  CHECK_THROWS_WITH(
      LoadFitConfig((dir / "fit.toml").string(), record, Mill5Scene()),
      Contains("fit.toml") && Contains("gain_bounds") && Contains("0 < lower <= 1 <= upper"));
}

}  // namespace millkit::identify

namespace millkit::identify {

TEST_CASE("logger time: a record shifted by 7.25 s fits to the same values") {
  Oscillogram record = Mill5Record(0.01, 12, 0.0, 3);
  Oscillogram shifted = record;
  for (double& t : shifted.time_s) t += 7.25;
  auto scene = Mill5Scene();
  const FitConfig config = Mill5Config(record, &scene);
  FitConfig shifted_config = config;
  shifted_config.window_start_s += 7.25;
  shifted_config.window_end_s += 7.25;
  const FitResult b = Fit(scene, shifted, shifted_config, FitOptions{});
  REQUIRE(b.summary.success);
  REQUIRE(b.time_origins_s.size() == 1);
  CHECK(b.time_origins_s[0] == 7.25);
  const auto compare = [&](const FitResult& a, double tolerance) {
    testing::CheckSameFit(a, b, tolerance);
  };
  SECTION("against the record whose times are the shifted ones less 7.25 s: the same fit") {
    // t + 7.25 rounds away the last bits of t; with the same model times the fits are the same.
    for (size_t k = 0; k < record.time_s.size(); ++k) record.time_s[k] = shifted.time_s[k] - 7.25;
    FitConfig exact = config;
    exact.window_end_s = shifted_config.window_end_s - 7.25;
    const FitResult a = Fit(scene, record, exact, FitOptions{});
    compare(a, 1e-9);
    CHECK(b.summary.simulations == a.summary.simulations);
  }
  SECTION("against the record as it was: within the fit's own convergence tolerance") {
    // The 1e-15 s time differences steer Levenberg–Marquardt along another path, which stops
    // within its parameter tolerance (1e-8 of the angle) of the same minimum.
    compare(Fit(scene, record, config, FitOptions{}), 1e-7);
  }
  SECTION("an explicit time origin after the first sample is refused") {
    shifted_config.time_origin_s = 7.3;
    CHECK_THROWS_WITH(Fit(scene, shifted, shifted_config, FitOptions{}),
                      Contains("time_origin") && Contains("first sample"));
  }
}

}  // namespace millkit::identify
