// The search's local fits (identify/multistart.h): a fit that comes back to a minimum already
// found stops there (FitOptions::rejoin_se), and only there. And the profiles followed with one
// parameter held (identify/uncertainty.h): the check of the standard errors, and the walk along
// a sharply curved valley.
// identify/fit_model.h comes first: glog (through Ceres) defines CHECK, which Catch's replaces.
// clang-format off
#include "identify/fit_model.h"
// clang-format on

#include "identify/multistart.h"

#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <limits>
#include <optional>
#include <random>

#include "identify/random_line.h"
#include "identify/record_noise.h"
#include "identify/uncertainty.h"
#include "millkit/identify/fit.h"

namespace millkit {
namespace {

// The fit's own weights: 1 / noise of each channel, as Fit sets them.
std::vector<double> NoiseWeights(const identify::Oscillogram& record,
                                 const identify::FitConfig& config) {
  std::vector<int> columns;
  for (const auto& c : config.channels) columns.push_back(record.ChannelIndex(c.column));
  const int quiet_end = identify::QuietStretchEnd(record, columns);
  const auto [begin, end] = record.WindowRange(config.window_start_s, config.window_end_s);
  std::vector<double> weights;
  weights.reserve(columns.size());
  for (const int column : columns) {
    weights.push_back(
        1.0 / identify::EstimateChannelNoise(record, column, quiet_end, begin, end).sigma_Nm);
  }
  return weights;
}

// A random line's model on its whole window, with the fit's own weights, and the minimum that
// Levenberg–Marquardt reaches from the truth.
struct LineFromTruth {
  explicit LineFromTruth(unsigned long seed)
      : line(identify::MakeRandomLineCase(seed)),
        records{line.record},
        model(line.prior, records, line.config, NoiseWeights(line.record, line.config)) {
    model.SetStage(1.0);
    std::vector<double> truth(model.parameters());
    for (int i = 0; i < model.parameters(); ++i) truth[i] = model.Unit(i, line.truth_values[i]);
    minimum = identify::Refine(model, identify::FitOptions{}, truth, true, 100);
  }
  identify::RandomLineCase line;
  std::vector<identify::Oscillogram> records;
  identify::FitModel model;
  identify::LocalFit minimum;
};

// The linearisation at a line's minimum from the truth: what the profile check starts from.
struct Linearised {
  explicit Linearised(const LineFromTruth& line) {
    const identify::FitModel& model = line.model;
    const identify::FitOptions options;
    REQUIRE(line.minimum.converged);
    Eigen::VectorXd r;
    std::vector<identify::Nuisance> nuisance;
    REQUIRE(model.ProjectedResiduals(line.minimum.u.data(), &r, &nuisance));
    REQUIRE(model.FullJacobian(line.minimum.u, nuisance, options.derivative_step,
                               options.derivatives, &r, &jacobian));
    fitted = model.FittedIndices();
    cost = 0.5 * r.squaredNorm();
    noise_scale = std::sqrt(2.0 * cost / static_cast<double>(model.residuals() - fitted.size()));
    covariance = identify::Covariance(jacobian, fitted, noise_scale);
  }
  Eigen::MatrixXd jacobian;
  std::vector<int> fitted;
  double cost = 0.0;
  double noise_scale = 0.0;
  Eigen::MatrixXd covariance;
};

}  // namespace

TEST_CASE("A fit that comes back to a known minimum stops there, and only there", "[fit]") {
  std::mt19937_64 random(5);
  for (const unsigned long seed : {3ul, 12ul, 305ul}) {
    INFO("seed " << seed);
    const LineFromTruth fixture(seed);
    const identify::FitModel& model = fixture.model;
    const identify::LocalFit& minimum = fixture.minimum;
    const identify::FitOptions options;
    const int p = model.parameters();
    REQUIRE(minimum.converged);
    REQUIRE(minimum.precision.rows() == p);

    // A point 3 standard errors (Mahalanobis) away in a random direction, as a basin hop.
    const Eigen::LLT<Eigen::MatrixXd> factor(minimum.precision);
    REQUIRE(factor.info() == Eigen::Success);
    Eigen::VectorXd z(p);
    for (int i = 0; i < p; ++i) z[i] = std::normal_distribution<double>()(random);
    const Eigen::VectorXd step = factor.matrixU().solve(3.0 * z / z.norm());
    std::vector<double> hop(p);
    for (int i = 0; i < p; ++i) {
      hop[i] = identify::ParameterMap::UnitFromAngle(
          identify::ParameterMap::AngleFromUnit(minimum.u[i]) + step[i]);
    }
    // PrecisionLength measures it so (the step is 3 / ‖z‖ z in the Cholesky factor's units).
    REQUIRE(identify::PrecisionLength(minimum, hop) == Approx(3.0).epsilon(0.05));

    const identify::LocalFit alone = identify::Refine(model, options, hop, true, 100);
    const identify::LocalFit back = identify::Refine(model, options, hop, true, 100, {}, &minimum);
    // Left alone the fit reaches the same minimum, within the rough floor of the misfit ...
    REQUIRE(alone.converged);
    CHECK_FALSE(alone.rejoined);
    CHECK(identify::PrecisionLength(minimum, alone.u) <= 0.3);
    // ... which the fit told of it stops at, no later, and returns exactly.
    CHECK(back.rejoined);
    CHECK(back.converged);
    CHECK(back.u == minimum.u);
    CHECK(back.cost == minimum.cost);
    CHECK(back.summary.iterations.size() <= alone.summary.iterations.size());

    // A known point whose χ² is 10 higher than what lies next to it is not that minimum.
    identify::LocalFit worse = minimum;
    worse.cost += 5.0;
    const identify::LocalFit below = identify::Refine(model, options, hop, true, 100, {}, &worse);
    CHECK_FALSE(below.rejoined);
    CHECK(below.cost < worse.cost - 4.0);

    // Without a precision there is nothing to measure the way back in.
    identify::LocalFit unmeasured = minimum;
    unmeasured.precision.resize(0, 0);
    CHECK_FALSE(identify::Refine(model, options, hop, true, 100, {}, &unmeasured).rejoined);
    CHECK(std::isinf(identify::PrecisionLength(unmeasured, hop)));
    CHECK(identify::PrecisionLength(minimum, minimum.u) == 0.0);
  }
}

// Random line 555 (six masses, two 1.07 mrad gaps): at the minimum, 8.9 linearised standard
// errors from the motor coupling's true backlash, the misfit is quadratic along the straight
// profile direction; the truth lies in a valley that curves away from it.
TEST_CASE("The profile check follows a valley that curves away from the straight line", "[fit]") {
  const LineFromTruth fixture(555);
  const identify::FitModel& model = fixture.model;
  const identify::LocalFit& minimum = fixture.minimum;
  const identify::FitOptions options;
  const int p = model.parameters();
  const Linearised at(fixture);
  const Eigen::MatrixXd& jacobian = at.jacobian;
  const std::vector<int>& fitted = at.fitted;
  const double cost = at.cost;
  const double noise_scale = at.noise_scale;
  const Eigen::MatrixXd& covariance = at.covariance;

  identify::FitOptions straight_only;
  straight_only.profile_relax_widening = 0.0;
  std::optional<identify::ProfileProbe> lower = identify::ProfileProbe{};
  int walks = -1;
  const auto straight =
      identify::ProfileWidening(model, minimum.u, jacobian, fitted, covariance, cost, noise_scale,
                                straight_only, {}, {}, &lower, &walks);
  CHECK_FALSE(lower.has_value());
  CHECK(walks == 0);
  const auto relaxed =
      identify::ProfileWidening(model, minimum.u, jacobian, fitted, covariance, cost, noise_scale,
                                options, {}, {}, &lower, &walks);
  CHECK_FALSE(lower.has_value());
  CHECK(walks >= 1);
  for (int i = 0; i < p; ++i) {
    const std::string& name = model.slot(i).name;
    INFO(name << ": straight x" << straight[i] << ", relaxed x" << relaxed[i]);
    // Relaxing only ever widens.
    CHECK(relaxed[i] >= straight[i]);
    const double linearised =
        std::sqrt(covariance(i, i)) * model.slot(i).map.PhysicalPerUnit(minimum.u[i]);
    const double off =
        std::abs(model.Physical(i, minimum.u[i]) - fixture.line.truth_values[i]) / linearised;
    if (name == "motor_coupling_hub.backlash") {
      CHECK(straight[i] < 1.2);
      CHECK(off / straight[i] > 5.0);  // the straight probes leave it a silent wrong answer
      CHECK(relaxed[i] > 3.0);
      CHECK(off / relaxed[i] < 3.0);
    } else {
      CHECK(off / relaxed[i] < 3.0);
    }
  }
}

// A point held on a walk (here one inward from a bound, given as such) moved parameters by d at
// a χ² Δ above the minimum: under the linearisation no point at Δ lies further than √Δ
// standard errors in any parameter, so each error widens to d / √max(Δ, 1), the held
// parameter's and the others'. A point past profile_chi2 says nothing; the parameters it did
// not move keep their widening.
TEST_CASE("A held point widens every standard error it moved further than its chi2 allows",
          "[fit]") {
  const LineFromTruth fixture(555);
  const identify::FitModel& model = fixture.model;
  const Linearised at(fixture);
  identify::FitOptions options;
  options.profile_relax_widening = 0.0;  // no profile followed: only the given point widens
  // Two linearly mapped parameters (unit steps are physical ones): the held one and another.
  std::vector<int> linear;
  for (int i = 0; i < model.parameters(); ++i) {
    if (!model.slot(i).map.log_scale()) linear.push_back(i);
  }
  REQUIRE(linear.size() >= 2);
  const int slot = linear[0];
  const int other = linear[1];
  std::optional<identify::ProfileProbe> lower;
  const auto without =
      identify::ProfileWidening(model, fixture.minimum.u, at.jacobian, at.fitted, at.covariance,
                                at.cost, at.noise_scale, options, {}, {}, &lower);
  const auto held_at = [&](double chi2) {
    identify::ProfileProbe point{slot, fixture.minimum.u,
                                 at.cost + 0.5 * chi2 * at.noise_scale * at.noise_scale};
    point.u[slot] += 6.0 * std::sqrt(at.covariance(slot, slot));     // 6 standard errors
    point.u[other] -= 4.0 * std::sqrt(at.covariance(other, other));  // and 4 in another
    return identify::ProfileWidening(model, fixture.minimum.u, at.jacobian, at.fitted,
                                     at.covariance, at.cost, at.noise_scale, options, {}, {point},
                                     &lower);
  };
  const auto near = held_at(4.0);  // at χ² 4: 3 and 2 times the linearised errors
  const auto far = held_at(30.0);  // past profile_chi2 (25)
  for (int i = 0; i < model.parameters(); ++i) {
    INFO(model.slot(i).name << ": without x" << without[i] << ", near x" << near[i]);
    CHECK(far[i] == without[i]);
    if (i == slot) {
      CHECK(near[i] == Approx(std::max(3.0, without[i])).epsilon(1e-9));
    } else if (i == other) {
      CHECK(near[i] == Approx(std::max(2.0, without[i])).epsilon(1e-9));
    } else {
      CHECK(near[i] == without[i]);
    }
  }
  // The same point held across a gap's range: the same rule, with nothing else widening.
  identify::ProfileProbe point{slot, fixture.minimum.u,
                               at.cost + 2.0 * at.noise_scale * at.noise_scale};  // χ² 4
  point.u[slot] += 6.0 * std::sqrt(at.covariance(slot, slot));
  point.u[other] -= 4.0 * std::sqrt(at.covariance(other, other));
  const auto across = identify::GapRangeWidening(model, fixture.minimum.u, at.covariance, at.cost,
                                                 at.noise_scale, options, {point});
  for (int i = 0; i < model.parameters(); ++i) {
    CHECK(across[i] == Approx(i == slot ? 3.0 : i == other ? 2.0 : 1.0).epsilon(1e-9));
  }
}

namespace {

// The slot of the model's last fitted backlash; −1 when none is fitted.
int LastGapSlot(const identify::FitModel& model) {
  int gap = -1;
  for (int i = 0; i < model.parameters(); ++i) {
    if (model.free(i).parameter.kind == driveline::SceneParameter::Kind::kBacklash) gap = i;
  }
  return gap;
}

// Standard errors 2, 1, 3; correlation 0.6 between the first two, none with the third.
Eigen::MatrixXd TwoCorrelatedOfThree() {
  Eigen::MatrixXd covariance(3, 3);
  covariance << 4.0, 1.2, 0.0,  //
      1.2, 1.0, 0.0,            //
      0.0, 0.0, 9.0;
  return covariance;
}

}  // namespace

// A widened parameter carries what is correlated with it: its own spread ×w, a quantity with
// correlation ρ to it ×√(1 + (w² − 1) ρ²), their covariance ×w² (its regression on the widened
// one kept), an uncorrelated one untouched. A factor of 1 or ∞ (a lower cost found) widens
// nothing.
TEST_CASE("Widening a parameter's error widens what is correlated with it", "[fit]") {
  const Eigen::MatrixXd covariance = TwoCorrelatedOfThree();
  Eigen::MatrixXd widened = covariance;
  identify::WidenAlongProfiles({3.0, 1.0, 1.0}, &widened);
  CHECK(widened(0, 0) == Approx(9.0 * 4.0));
  CHECK(widened(1, 1) == Approx(1.0 + 8.0 * 0.36));
  CHECK(widened(0, 1) == Approx(9.0 * 1.2));
  CHECK(widened(1, 0) == widened(0, 1));
  CHECK(widened(2, 2) == 9.0);
  CHECK(widened(0, 2) == 0.0);
  // Two at once: each term from the covariance as given, whatever the order of the slots.
  Eigen::MatrixXd both = covariance;
  identify::WidenAlongProfiles({3.0, 2.0, 1.0}, &both);
  const Eigen::MatrixXd expected = covariance +
                                   8.0 / 4.0 * covariance.col(0) * covariance.col(0).transpose() +
                                   3.0 / 1.0 * covariance.col(1) * covariance.col(1).transpose();
  CHECK((both - expected).norm() < 1e-12);
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> spectrum(both);
  CHECK(spectrum.eigenvalues().minCoeff() > 0.0);
  Eigen::MatrixXd same = covariance;
  identify::WidenAlongProfiles({1.0, std::numeric_limits<double>::infinity(), 1.0}, &same);
  CHECK(same == covariance);
}

// A widening `alone` (points held far beyond the linearisation's reach, across a gap's range)
// scales the parameter's row and column: its correlations stay, nothing is carried over; and it
// only ever raises the variance to its factor² times the one given, whatever the other widening
// did first.
TEST_CASE("Widening a parameter's error alone keeps its correlations", "[fit]") {
  const Eigen::MatrixXd covariance = TwoCorrelatedOfThree();
  Eigen::MatrixXd alone = covariance;
  identify::WidenAlongProfiles({1.0, 1.0, 1.0}, &alone, {3.0, 1.0, 1.0});
  CHECK(alone(0, 0) == Approx(9.0 * 4.0));
  CHECK(alone(1, 1) == 1.0);
  CHECK(alone(0, 1) == Approx(3.0 * 1.2));
  CHECK(alone(1, 0) == alone(0, 1));
  CHECK(alone(2, 2) == 9.0);
  // Carried over ×2 first (variance 16), then raised to 3² × 4 = 36: row and column ×1.5.
  Eigen::MatrixXd both = covariance;
  identify::WidenAlongProfiles({2.0, 1.0, 1.0}, &both, {3.0, 1.0, 1.0});
  Eigen::MatrixXd carried = covariance;
  identify::WidenAlongProfiles({2.0, 1.0, 1.0}, &carried);
  CHECK(both(0, 0) == Approx(36.0));
  CHECK(both(0, 1) == Approx(1.5 * carried(0, 1)));
  CHECK(both(1, 1) == carried(1, 1));
  // A factor below what the carried widening reached changes nothing.
  Eigen::MatrixXd less = covariance;
  identify::WidenAlongProfiles({2.0, 1.0, 1.0}, &less, {1.5, 1.0, 1.0});
  CHECK(less == carried);
}

// Each fitted gap is kicked gap_kick × 2ᵏ wider and narrower, k < gap_kick_levels (2 % and 4 % by
// default), the other quantities as they are; the option is checked.
TEST_CASE("Gap kicks come at gap_kick and twice it in either direction", "[fit]") {
  const LineFromTruth fixture(526);
  const identify::FitModel& model = fixture.model;
  const std::vector<double>& u = fixture.minimum.u;
  const int gap = LastGapSlot(model);
  REQUIRE(gap >= 0);
  const double at = model.Physical(gap, u[gap]);
  identify::FitOptions options;
  const auto kicks = identify::GapKicks(model, u, options);
  std::vector<double> ratios;
  for (const auto& point : kicks) {
    for (int i = 0; i < model.parameters(); ++i) {
      if (i != gap) CHECK(point[i] == u[i]);
    }
    ratios.push_back(model.Physical(gap, point[gap]) / at);
  }
  std::sort(ratios.begin(), ratios.end());
  REQUIRE(ratios.size() == 4);
  CHECK(ratios[0] == Approx(0.96).epsilon(1e-9));
  CHECK(ratios[1] == Approx(0.98).epsilon(1e-9));
  CHECK(ratios[2] == Approx(1.02).epsilon(1e-9));
  CHECK(ratios[3] == Approx(1.04).epsilon(1e-9));
  options.gap_kick_levels = 1;
  CHECK(identify::GapKicks(model, u, options).size() == 2);
  options.gap_kick_levels = 0;
  CHECK_THROWS_WITH(options.Validate(), Catch::Contains("gap_kick_levels"));
  options.gap_kick_levels = 9;
  CHECK_THROWS_WITH(options.Validate(), Catch::Contains("gap_kick_levels"));
}

// Each fitted gap is held at (k + ½)/gap_profile_points of its range (unit coordinates), the
// others refitted, except near the minimum, where the profile check probes; the option is
// checked.
TEST_CASE("A gap is held across its range", "[fit]") {
  const LineFromTruth fixture(526);
  const identify::FitModel& model = fixture.model;
  const std::vector<double>& u = fixture.minimum.u;
  const int gap = LastGapSlot(model);
  REQUIRE(gap >= 0);
  identify::FitOptions options;
  std::vector<identify::ProfileProbe> walks;
  std::vector<identify::ProfileProbe> gap_points;
  identify::CurvedValleyPoints(model, u, fixture.minimum.cost, options, &walks, &gap_points);
  std::vector<bool> held(options.gap_profile_points, false);
  for (const auto& point : gap_points) {
    CHECK(point.slot == gap);
    const double k = point.u[gap] * options.gap_profile_points - 0.5;
    CHECK(k == Approx(std::round(k)).margin(1e-12));
    const auto index = static_cast<size_t>(std::lround(k));
    REQUIRE(index < held.size());
    CHECK_FALSE(held[index]);
    held[index] = true;
    CHECK(point.cost >= fixture.minimum.cost);  // the truth's minimum: nothing lower
  }
  for (size_t k = 0; k < held.size(); ++k) {
    const double at = (static_cast<double>(k) + 0.5) / options.gap_profile_points;
    INFO("k " << k << ", at " << at << ", the minimum at " << u[gap]);
    if (!held[k]) CHECK(std::abs(at - u[gap]) < 1.0 / options.gap_profile_points);
  }
  CHECK(gap_points.size() >= held.size() - 2);
  options.gap_profile_points = 0;
  gap_points.clear();
  identify::CurvedValleyPoints(model, u, fixture.minimum.cost, options, &walks, &gap_points);
  CHECK(gap_points.empty());
  options.gap_profile_points = -1;
  CHECK_THROWS_WITH(options.Validate(), Catch::Contains("gap_profile_points"));
  options.gap_profile_points = 65;
  CHECK_THROWS_WITH(options.Validate(), Catch::Contains("gap_profile_points"));
}

// Random line 526 (3 masses, one channel, a 17.7 mrad gap): the search without the curved-valley
// walk ends in a minimum whose χ² is 106 above the truth's. Two standard errors along its
// straight profile directions the cost rises far above the prediction; followed with one
// parameter held, the valley leads down to the truth's minimum.
TEST_CASE("A sharply curved valley is followed down to a lower one", "[fit]") {
  const LineFromTruth fixture(526);
  const identify::FitModel& model = fixture.model;
  REQUIRE(fixture.minimum.converged);
  identify::FitOptions options;
  options.curved_valley_ratio = 0.0;
  options.gap_kick = 0.0;  // which reach the lower valley too
  const identify::FitResult unfollowed =
      identify::Fit(fixture.line.prior, fixture.line.record, fixture.line.config, options);
  REQUIRE(unfollowed.summary.success);
  std::vector<double> u(model.parameters());
  for (int i = 0; i < model.parameters(); ++i) {
    u[i] = model.Unit(i, unfollowed.parameters[i].value);
  }
  const identify::LocalFit wrong = identify::Refine(model, options, u, true, 100);
  REQUIRE(wrong.cost > fixture.minimum.cost + 20.0);
  std::vector<identify::ProfileProbe> bound_walks;
  std::vector<identify::ProfileProbe> gap_points;
  CHECK(identify::CurvedValleyPoints(model, wrong.u, wrong.cost, options, &bound_walks, &gap_points)
            .empty());

  options.curved_valley_ratio = identify::FitOptions{}.curved_valley_ratio;
  const auto lower =
      identify::CurvedValleyPoints(model, wrong.u, wrong.cost, options, &bound_walks, &gap_points);
  REQUIRE_FALSE(lower.empty());
  double previous = -1.0;
  for (const auto& point : lower) {
    const double cost = model.ProjectedCost(point.data());
    CHECK(cost < wrong.cost - 0.5);
    CHECK(cost >= previous);  // lowest first
    previous = cost;
  }
  const identify::LocalFit found = identify::Refine(model, options, lower.front(), true, 100);
  CHECK(found.cost == Approx(fixture.minimum.cost).epsilon(1e-4));
  // From the truth's minimum nothing lies lower.
  CHECK(identify::CurvedValleyPoints(model, fixture.minimum.u, fixture.minimum.cost, options,
                                     &bound_walks, &gap_points)
            .empty());
}

// Random line 883 (5 masses, one channel, three gaps; a seed the defaults were not tuned on):
// the search ended in a valley χ² 55 above the truth's, the damping of the motor's coupling
// pressed against its lower bound and 12 standard errors off. Its straight profiles do not bend
// enough for a curved-valley walk. Walked inward from that bound, with the damping held at 1/16,
// 1/8, 1/4 and 1/2 of its range and the others refitted, the profile leads to a lower valley.
TEST_CASE("A parameter at its bound has its profile followed inward", "[fit]") {
  const LineFromTruth fixture(883);
  const identify::FitModel& model = fixture.model;
  identify::FitOptions options;
  options.gap_profile_points = 0;  // the lower valley found by the walk alone
  // Where the search ended before the walk (minima[] of its fit.json).
  const std::vector<std::pair<std::string, double>> ended = {
      {"spindle1.damping", 2.66e5},     {"spindle1.backlash", 0.0024321},
      {"motor_hub2.damping", 16326.0},  {"motor_hub2.backlash", 0.00061417},
      {"hub2_hub3.damping", 5582.9},    {"spindle4.damping", 7122.9},
      {"spindle4.backlash", 0.0023843}, {"bite_time", 0.056697}};
  REQUIRE(model.parameters() == static_cast<int>(ended.size()));
  std::vector<double> u(model.parameters());
  for (int i = 0; i < model.parameters(); ++i) {
    REQUIRE(model.slot(i).name == ended[i].first);
    u[i] = std::clamp(model.Unit(i, ended[i].second), 0.0, 1.0);
  }
  const identify::LocalFit wrong = identify::Refine(model, options, u, true, 100);
  REQUIRE(wrong.usable);
  REQUIRE(wrong.u[2] <= identify::kAtBound);  // motor_hub2.damping at its lower bound
  REQUIRE(wrong.cost > fixture.minimum.cost + 20.0);

  std::vector<identify::ProfileProbe> walks;
  std::vector<identify::ProfileProbe> gap_points;
  const auto lower =
      identify::CurvedValleyPoints(model, wrong.u, wrong.cost, options, &walks, &gap_points);
  CHECK(gap_points.empty());
  REQUIRE(walks.size() == 4);
  for (size_t k = 0; k < walks.size(); ++k) {
    CHECK(walks[k].slot == 2);
    CHECK(walks[k].u[2] == Approx(std::ldexp(1.0, static_cast<int>(k) - 4)));  // 1/16 … 1/2
  }
  REQUIRE_FALSE(lower.empty());
  CHECK(model.ProjectedCost(lower.front().data()) < wrong.cost - 1.0);
  // From the truth's minimum, where nothing is at a bound, there is no walk.
  walks.clear();
  identify::CurvedValleyPoints(model, fixture.minimum.u, fixture.minimum.cost, options, &walks,
                               &gap_points);
  CHECK(walks.empty());
}

// Two starts whose continuations end a stage at the same point go on as one
// (FitOptions::merge_distance): the later takes the earlier one's continued fit, for fewer runs.
TEST_CASE("Starts whose continuations meet go on as one", "[fit]") {
  const LineFromTruth fixture(1);
  identify::FitModel model = fixture.model;
  const int p = model.parameters();
  std::vector<double> start(p), truth(p);
  for (int i = 0; i < p; ++i) {
    start[i] = model.Unit(i, fixture.line.config.free[i].start);
    truth[i] = model.Unit(i, fixture.line.truth_values[i]);
  }
  // The same start twice follows the same path twice: merged after the first stage, the answer
  // is the same to the last bit.
  const std::vector<std::vector<double>> starts = {start, truth, start};
  identify::FitOptions apart;
  apart.merge_distance = 0.0;
  const long before_apart = model.simulations();
  const auto separate = identify::RefineStarts(&model, apart, starts);
  const long runs_apart = model.simulations() - before_apart;
  const identify::FitOptions merged_options;
  for (const int threads : {1, 2}) {
    INFO(threads << " threads");
    identify::FitOptions options = merged_options;
    options.threads = threads;
    const long before = model.simulations();
    const auto merged = identify::RefineStarts(&model, options, starts);
    const long runs = model.simulations() - before;
    REQUIRE(merged.size() == separate.size());
    for (size_t k = 0; k < merged.size(); ++k) {
      INFO("minimum " << k << " of start " << separate[k].start);
      CHECK(merged[k].start == separate[k].start);
      // The third start joined the first; the second went its own way or joined the first, and
      // either way ends where it would have alone, within the rough floor of the misfit.
      if (separate[k].start != 1) {
        CHECK(merged[k].u == separate[k].u);
        CHECK(merged[k].cost == separate[k].cost);
      } else {
        CHECK(merged[k].cost == Approx(separate[k].cost).epsilon(1e-6));
      }
    }
    CHECK(runs < runs_apart);
  }
}

// A whole fit of a random line whose four starts meet after two stages: the same answer to
// 0.001 standard errors for a fifth fewer runs (572 against 733).
TEST_CASE("A fit whose starts meet early gives the same answer for fewer runs", "[fit]") {
  const identify::RandomLineCase line = identify::MakeRandomLineCase(1);
  identify::FitOptions apart;
  apart.merge_distance = 0.0;
  const identify::FitResult separate = identify::Fit(line.prior, line.record, line.config, apart);
  const identify::FitResult merged = identify::Fit(line.prior, line.record, line.config, {});
  REQUIRE(separate.summary.success);
  REQUIRE(merged.summary.success);
  CHECK(merged.summary.verdict == separate.summary.verdict);
  CHECK(merged.summary.starts_at_best == separate.summary.starts_at_best);
  REQUIRE(merged.parameters.size() == separate.parameters.size());
  for (size_t i = 0; i < merged.parameters.size(); ++i) {
    INFO(merged.parameters[i].name);
    CHECK(std::abs(merged.parameters[i].value - separate.parameters[i].value) <=
          1e-3 * separate.parameters[i].standard_error);
    CHECK(merged.parameters[i].standard_error ==
          Approx(separate.parameters[i].standard_error).epsilon(1e-3));
  }
  CHECK(merged.summary.simulations < 0.85 * separate.summary.simulations);
}

// The minimum's floor (FloorCost): what the creep stop lets its window of iterations gain, and
// nothing where that stop is off (no creep window, or no remaining-step stop to carry it).
TEST_CASE("The floor a probe must clear is the creep stop's slack, 0 without that stop", "[fit]") {
  identify::FitOptions options;
  CHECK(identify::FloorCost(options) == Approx(options.creep_iterations * 1e-3));
  CHECK(identify::FloorCost(options) > 0.0);
  options.creep_iterations = 10;
  CHECK(identify::FloorCost(options) == Approx(0.01));
  options.creep_iterations = 0;
  CHECK(identify::FloorCost(options) == 0.0);
  options.creep_iterations = 25;
  options.remaining_step_se = 0.0;
  CHECK(identify::FloorCost(options) == 0.0);
}

}  // namespace millkit
