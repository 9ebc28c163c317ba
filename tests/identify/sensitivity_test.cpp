// Forward sensitivities (millkit/driveline/sensitivity.h) against central differences of the
// simulation, at random parameter points of random lines (identify/random_line.h) under every
// contact law (issue 15 item 1).
#include "millkit/driveline/sensitivity.h"

#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdio>
#include <random>
#include <stdexcept>
#include <string>

#include "identify/random_line.h"
#include "millkit/io/input_error.h"

namespace millkit {
namespace {

using driveline::SceneParameter;

// Central differences of every link torque sample over parameter `parameter` at its value in
// `scene`, with absolute steps h and h/2, extrapolated (Richardson: (4 D(h/2) − D(h)) / 3, error
// O(h⁴); after a hundred impacts the torques are far from linear in a parameter, and D(h) alone
// is off by 1e-5 of its size). False when a neighbour's run fails or has another event count (the
// event sequence is not locally constant there). `kinks` gets the time intervals the events (and,
// for the bite time, the breakpoints) sweep between the runs: a sample inside one sees a kink or
// a jump of the torque move past it, which no derivative describes.
bool CentralDifference(const driveline::Scene& scene, const SceneParameter& parameter,
                       const driveline::SimulationOptions& options, double step, long events,
                       Eigen::MatrixXd* derivative, Eigen::MatrixXd* spread,
                       std::vector<std::pair<double, double>>* kinks) {
  const double value = parameter.Get(scene);
  const double offsets[4] = {step, -step, 0.5 * step, -0.5 * step};
  Eigen::MatrixXd torque[4];
  std::vector<double> low, high;
  for (int i = 0; i < 4; ++i) {
    driveline::Scene probe = scene;
    parameter.Set(value + offsets[i], &probe);
    const auto result = driveline::Simulate(driveline::Model(probe), options);
    if (!result.summary.success || result.summary.events != events) return false;
    torque[i] = result.link_torque_Nm;
    const auto& times = result.summary.event_times_s;
    if (i == 0) {
      low = high = times;
    } else {
      for (long e = 0; e < events; ++e) {
        low[e] = std::min(low[e], times[e]);
        high[e] = std::max(high[e], times[e]);
      }
    }
  }
  const Eigen::MatrixXd coarse = (torque[0] - torque[1]) / (2.0 * step);
  const Eigen::MatrixXd fine = (torque[2] - torque[3]) / step;
  *derivative = (4.0 * fine - coarse) / 3.0;
  *spread = fine - coarse;
  kinks->clear();
  for (long e = 0; e < events; ++e) kinks->emplace_back(low[e], high[e]);
  if (parameter.kind == SceneParameter::Kind::kBiteTime) {
    for (double t : scene.InputBreakpoints()) kinks->emplace_back(t - step, t + step);
  }
  return true;
}

// Rows of `matrix` at the times inside none of the intervals; the count of rows removed.
int DropKinks(const std::vector<double>& time, const std::vector<std::pair<double, double>>& kinks,
              Eigen::MatrixXd* matrix) {
  int kept = 0;
  for (int k = 0; k < matrix->rows(); ++k) {
    const bool inside = std::any_of(kinks.begin(), kinks.end(), [&](const auto& kink) {
      return time[k] >= kink.first && time[k] <= kink.second;
    });
    if (!inside) matrix->row(kept++) = matrix->row(k);
  }
  const int dropped = static_cast<int>(matrix->rows()) - kept;
  matrix->conservativeResize(kept, Eigen::NoChange);
  return dropped;
}

struct Tally {
  int points = 0;    // parameter points compared in full
  int compared = 0;  // parameter columns compared
  int skipped = 0;   // columns whose neighbours change the event count
  int unavailable = 0;
  long samples = 0;    // samples of the compared columns
  long dropped = 0;    // of them, inside the interval an event sweeps (CentralDifference)
  int noisy = 0;       // columns within the differences' spread only
  double worst = 0.0;  // largest difference / allowed

  void Print(const char* label) const {
    std::printf(
        "%s: %d points, %d columns compared, %d skipped, %d unavailable, worst difference / "
        "allowed %.3g, %ld of %ld samples next to an event, %d within the spread only\n",
        label, points, compared, skipped, unavailable, worst, dropped, samples, noisy);
  }
};

// The parameters of a scene: each link's damping and backlash, the first stiffness, the last
// inertia and load, the bite time and the first backlash link's gap position.
std::vector<SceneParameter> ParametersOf(const driveline::Scene& scene) {
  std::vector<SceneParameter> parameters;
  const auto add = [&](const std::string& name) {
    parameters.push_back(driveline::ParseSceneParameter(scene, name, "test"));
  };
  for (const auto& link : scene.links) {
    add(link.name + ".damping");
    if (link.backlash_rad > 0.0) add(link.name + ".backlash");
  }
  add(scene.links.front().name + ".stiffness");
  add(scene.masses.back().name + ".inertia");
  add(scene.masses.back().name + ".load");
  add("bite_time");
  for (const auto& link : scene.links) {
    if (link.backlash_rad > 0.0) {
      add(link.name + ".gap_position");
      break;
    }
  }
  return parameters;
}

// Moves every parameter to a random point (× [0.7, 1.3], bite time ± 5 ms, gap position in
// [−0.9, 0.9]) and compares the sensitivities with extrapolated central differences (steps 1e-5
// and 5e-6 of each parameter's magnitude).
void ComparePoint(driveline::Scene scene, std::mt19937_64* random, const char* label,
                  Tally* tally) {
  const auto parameters = ParametersOf(scene);
  for (const auto& parameter : parameters) {
    const double u = std::uniform_real_distribution<double>(0.0, 1.0)(*random);
    const double value = parameter.Get(scene);
    if (parameter.kind == SceneParameter::Kind::kBiteTime)
      parameter.Set(value + 0.01 * (u - 0.5), &scene);
    else if (parameter.kind == SceneParameter::Kind::kGapPosition)
      parameter.Set(-0.9 + 1.8 * u, &scene);
    else
      parameter.Set(value * (0.7 + 0.6 * u), &scene);
  }
  driveline::SimulationOptions options;
  options.estimate_error = false;
  const auto sensitivities = driveline::SimulateWithSensitivities(scene, parameters, options);
  REQUIRE(sensitivities.simulation.summary.success);
  if (!sensitivities.unavailable.empty()) {
    std::printf("%s: unavailable: %s\n", label, sensitivities.unavailable.c_str());
    ++tally->unavailable;
    return;
  }
  const long events = sensitivities.simulation.summary.events;
  const double peak = sensitivities.simulation.link_torque_Nm.cwiseAbs().maxCoeff();
  ++tally->points;
  for (size_t j = 0; j < parameters.size(); ++j) {
    const auto& parameter = parameters[j];
    const double value = parameter.Get(scene);
    const double scale = parameter.kind == SceneParameter::Kind::kBiteTime      ? 0.1
                         : parameter.kind == SceneParameter::Kind::kGapPosition ? 1.0
                                                                                : std::abs(value);
    // A parameter at its physical bound (the undamped two-mass scene's zero damping) has no
    // central difference.
    if (value == 0.0 && parameter.kind == SceneParameter::Kind::kDamping) {
      ++tally->skipped;
      continue;
    }
    Eigen::MatrixXd reference, spread;
    std::vector<std::pair<double, double>> kinks;
    if (!CentralDifference(scene, parameter, options, 1e-5 * scale, events, &reference, &spread,
                           &kinks)) {
      ++tally->skipped;
      continue;
    }
    Eigen::MatrixXd exact = sensitivities.link_torque[j];
    const auto& time = sensitivities.simulation.time_s;
    tally->dropped += DropKinks(time, kinks, &reference);
    DropKinks(time, kinks, &exact);
    DropKinks(time, kinks, &spread);
    tally->samples += static_cast<int>(time.size());
    // 1e-6 of the column's size, plus the differences' noise floor for a parameter the torques
    // hardly depend on: 1e-7 of the peak torque per parameter magnitude (a 100 % change moves
    // the torques by 1e-7 of their peak; the runs' roundoff, ≈ 4e-14 of the peak, divided by
    // the step 1e-5 is 25 times less). After a hundred impacts the runs' roundoff grows (each
    // event time's few ulps are amplified by the impacts after it) and the differences cannot
    // tell more than their own spread, |D(h/2) − D(h)|: such a column is checked to that, and
    // counted.
    const double size = reference.cwiseAbs().maxCoeff();
    const double difference = (exact - reference).cwiseAbs().maxCoeff();
    const double allowed = 1e-6 * size + 1e-7 * peak / scale;
    const double noise = 3.0 * spread.cwiseAbs().maxCoeff();
    tally->worst = std::max(tally->worst, difference / allowed);
    if (difference > allowed) ++tally->noisy;
    if (difference > allowed + noise) {
      Eigen::Index row = 0, col = 0;
      (exact - reference).cwiseAbs().maxCoeff(&row, &col);
      std::printf(
          "%s law %s %s: difference %.3g of %.3g (allowed %.3g + spread %.3g, events "
          "%ld; row %ld link %ld: %.6g vs %.6g)\n",
          label, driveline::ContactLawName(scene.contact), parameter.name.c_str(), difference, size,
          allowed, noise, events, static_cast<long>(row), static_cast<long>(col), exact(row, col),
          reference(row, col));
    }
    CHECK(difference <= allowed + noise);
    ++tally->compared;
  }
}

constexpr driveline::ContactLaw kLaws[] = {driveline::ContactLaw::kLimited,
                                           driveline::ContactLaw::kNoPull,
                                           driveline::ContactLaw::kLinear};

// Random lines of seeds first_seed … last_seed, 0.15 s long, the contact law by seed, until
// `points` points are compared; with `lowpass` a recorder low-pass on the first and the last link,
// its cutoff `cutoff` (a fraction of the sample rate, uniform in the range).
struct CutoffRange {
  double lower = 0.1, upper = 0.4;
};
Tally CompareRandomLines(unsigned long first_seed, unsigned long last_seed, int points,
                         bool lowpass, std::mt19937_64* random, CutoffRange cutoff = {}) {
  Tally tally;
  for (unsigned long seed = first_seed; tally.points < points && seed <= last_seed; ++seed) {
    driveline::Scene scene = identify::MakeRandomLineCase(seed).truth;
    scene.contact = kLaws[seed % 3];
    scene.duration_s = 0.15;
    if (lowpass) {
      for (const size_t l : {size_t{0}, scene.links.size() - 1}) {
        const double u =
            std::uniform_real_distribution<double>(cutoff.lower, cutoff.upper)(*random);
        scene.links[l].recorder_lowpass_Hz = u * scene.sample_rate_Hz;
      }
    }
    ComparePoint(scene, random, ("seed " + std::to_string(seed)).c_str(), &tally);
  }
  return tally;
}

TEST_CASE("Sensitivities agree with central differences at 200 points of random lines",
          "[sensitivity]") {
  std::mt19937_64 random(15);
  const Tally tally = CompareRandomLines(1, 260, 200, false, &random);
  tally.Print("random lines");
  CHECK(tally.points >= 200);
  CHECK(tally.noisy <= tally.compared / 100);
  CHECK(tally.unavailable <= 10);
}

// A recorder low-pass (Link::recorder_lowpass_Hz, what a fit puts on its channels' links) adds a
// state whose row holds the link's torque row: its sensitivities come through the same pass.
TEST_CASE("Sensitivities agree with central differences through a recorder low-pass",
          "[sensitivity]") {
  std::mt19937_64 random(17);
  const Tally tally = CompareRandomLines(301, 400, 60, true, &random);
  tally.Print("random lines through a recorder low-pass");
  CHECK(tally.points >= 60);
  CHECK(tally.noisy <= tally.compared / 100);
  CHECK(tally.unavailable <= 3);
}

// The pass carries a low-pass row exactly beside the Taylor series of the others (its decay
// through the series' polynomial, numerics/exponential_moments.h): a filter far faster than the
// line and the sampling (a time constant of 1/60 to 1/6 of a sample) takes it at e^{−aτ} down to
// underflow, on short legs and on the cached step alike.
TEST_CASE(
    "Sensitivities agree with central differences through a low-pass faster than the "
    "sampling",
    "[sensitivity]") {
  std::mt19937_64 random(18);
  const Tally tally = CompareRandomLines(401, 460, 20, true, &random, {1.0, 10.0});
  tally.Print("random lines through a fast recorder low-pass");
  CHECK(tally.points >= 20);
  CHECK(tally.noisy <= tally.compared / 100);
  CHECK(tally.unavailable <= 1);
}

TEST_CASE("Sensitivities agree with central differences on the bundled scenes", "[sensitivity]") {
  Tally tally;
  std::mt19937_64 random(16);
  for (const char* name : {"mill5_bite", "drive_pi", "two_mass_step", "mill5_stiff_motor"}) {
    const auto scene = driveline::LoadScene(std::string(MILLKIT_SOURCE_DIR) + "/datasets/scenes/" +
                                            name + ".toml");
    for (const auto law : kLaws) {
      for (int point = 0; point < 3; ++point) {
        driveline::Scene run = scene;
        run.contact = law;
        ComparePoint(run, &random, name, &tally);
      }
    }
  }
  tally.Print("bundled scenes");
  CHECK(tally.points >= 30);
  CHECK(tally.noisy <= tally.compared / 10);
}

// Asking for some links records those links' columns, in the order asked, bit for bit the same
// as with every link; a link the scene does not have is an input error.
TEST_CASE("Sensitivities of chosen links are those links' columns", "[sensitivity]") {
  const auto scene =
      driveline::LoadScene(std::string(MILLKIT_SOURCE_DIR) + "/datasets/scenes/mill5_bite.toml");
  const auto parameters = ParametersOf(scene);
  driveline::SimulationOptions options;
  options.estimate_error = false;
  const auto all = driveline::SimulateWithSensitivities(scene, parameters, options);
  REQUIRE(all.unavailable.empty());
  const std::vector<int> chosen{3, 1};
  const auto some = driveline::SimulateWithSensitivities(scene, parameters, options, chosen);
  REQUIRE(some.unavailable.empty());
  REQUIRE(some.link_torque.size() == parameters.size());
  for (size_t j = 0; j < parameters.size(); ++j) {
    REQUIRE(some.link_torque[j].cols() == 2);
    for (int i = 0; i < 2; ++i)
      CHECK(some.link_torque[j].col(i) == all.link_torque[j].col(chosen[i]));
  }
  CHECK(some.simulation.link_torque_Nm == all.simulation.link_torque_Nm);
  CHECK_THROWS_AS(driveline::SimulateWithSensitivities(scene, parameters, options, {5}),
                  InputError);
  CHECK_THROWS_AS(driveline::SimulateWithSensitivities(scene, parameters, options, {-1}),
                  InputError);
}

// A fit evaluates its misfit at a point and then asks for the derivatives there: the sensitivities
// along the kept run are those of a run with the pass attached, to the last bit, under every
// contact law (events whose right-hand side jumps), with a recorder low-pass, with a step load's
// breakpoint and a bite time among the parameters, and from a run whose stops outgrew their budget
// (not kept: the solver runs again); a failed run's reason comes through the same.
TEST_CASE("Sensitivities along a kept run are those of a run with the pass to the bit",
          "[sensitivity]") {
  std::vector<driveline::Scene> scenes;
  for (const char* name : {"mill5_bite", "drive_pi", "two_mass_step"}) {
    scenes.push_back(driveline::LoadScene(std::string(MILLKIT_SOURCE_DIR) + "/datasets/scenes/" +
                                          name + ".toml"));
  }
  for (unsigned long seed = 1; seed <= 6; ++seed) {
    driveline::Scene scene = identify::MakeRandomLineCase(seed).truth;
    scene.duration_s = 0.15;
    if (seed % 2 == 0) scene.links.back().recorder_lowpass_Hz = 0.3 * scene.sample_rate_Hz;
    scenes.push_back(std::move(scene));
  }
  int compared = 0, jumps = 0;
  for (const auto& base : scenes) {
    for (const auto law : kLaws) {
      driveline::Scene scene = base;
      scene.contact = law;
      const auto parameters = ParametersOf(scene);
      driveline::SimulationOptions options;
      options.estimate_error = false;
      const std::vector<int> links{0, static_cast<int>(scene.links.size()) - 1};
      const auto direct = driveline::SimulateWithSensitivities(scene, parameters, options, links);
      options.keep_samples = false;  // as a fit's plain run: the kept run need not keep samples
      const driveline::RecordedRun kept(scene, options);
      REQUIRE_FALSE(kept.empty());
      const auto along = driveline::SimulateWithSensitivities(kept, parameters, links);
      INFO(scene.name << ", law " << static_cast<int>(law));
      CHECK(along.unavailable == direct.unavailable);
      CHECK(along.simulation.summary.events == direct.simulation.summary.events);
      CHECK(along.simulation.summary.event_times_s == direct.simulation.summary.event_times_s);
      CHECK(along.simulation.peak_abs_torque_Nm == direct.simulation.peak_abs_torque_Nm);
      CHECK(along.simulation.link_torque_Nm.size() == 0);  // the kept run's samples: none
      REQUIRE(along.link_torque.size() == direct.link_torque.size());
      for (size_t j = 0; j < along.link_torque.size(); ++j) {
        CHECK(along.link_torque[j] == direct.link_torque[j]);
      }
      // Stops beyond the budget are not kept: the pass then runs the solver again.
      CHECK(kept.stops_kept());
      const driveline::RecordedRun small(scene, options, 1024);
      CHECK_FALSE(small.stops_kept());
      const auto again = driveline::SimulateWithSensitivities(small, parameters, links);
      CHECK(again.unavailable == direct.unavailable);
      REQUIRE(again.link_torque.size() == direct.link_torque.size());
      for (size_t j = 0; j < again.link_torque.size(); ++j) {
        CHECK(again.link_torque[j] == direct.link_torque[j]);
      }
      if (direct.unavailable.empty()) ++compared;
      if (law != driveline::ContactLaw::kLimited && direct.simulation.summary.events > 0) ++jumps;
    }
  }
  CHECK(compared >= 20);
  CHECK(jumps >= 10);

  // A run that fails (too many events) is kept with its reason.
  auto scene = scenes.front();
  driveline::SimulationOptions options;
  options.estimate_error = false;
  options.max_events = 1;
  const auto parameters = ParametersOf(scene);
  const auto direct = driveline::SimulateWithSensitivities(scene, parameters, options);
  const driveline::RecordedRun kept(scene, options);
  const auto along = driveline::SimulateWithSensitivities(kept, parameters);
  CHECK_FALSE(direct.simulation.summary.success);
  CHECK_FALSE(along.simulation.summary.success);
  CHECK(along.unavailable == direct.unavailable);
  CHECK(along.unavailable.rfind("the run failed: more than max_events", 0) == 0);
  CHECK_THROWS_AS(driveline::SimulateWithSensitivities(kept, parameters, {7}), InputError);
  CHECK_THROWS_AS(driveline::SimulateWithSensitivities(driveline::RecordedRun(), parameters),
                  std::logic_error);
}

}  // namespace
}  // namespace millkit
