// The search's local fits (identify/multistart.h): a fit that comes back to a minimum already
// found stops there (FitOptions::rejoin_se), and only there.
// identify/fit_model.h comes first: glog (through Ceres) defines CHECK, which Catch's replaces.
#include "identify/fit_model.h"
#undef CHECK

#include <catch2/catch.hpp>
#include <cmath>
#include <random>

#include "identify/multistart.h"
#include "identify/random_line.h"
#include "identify/record_noise.h"
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

// The Mahalanobis length of a − b (unit coordinates) under the precision of `at` (angles).
double Length(const std::vector<double>& a, const std::vector<double>& b,
              const identify::LocalFit& at) {
  Eigen::VectorXd d(a.size());
  for (size_t i = 0; i < a.size(); ++i) {
    d[i] =
        identify::ParameterMap::AngleFromUnit(a[i]) - identify::ParameterMap::AngleFromUnit(b[i]);
  }
  return std::sqrt(d.dot(at.precision * d));
}

}  // namespace

TEST_CASE("A fit that comes back to a known minimum stops there, and only there", "[fit]") {
  std::mt19937_64 random(5);
  for (const unsigned long seed : {3ul, 12ul, 305ul}) {
    INFO("seed " << seed);
    const auto line = identify::MakeRandomLineCase(seed);
    const std::vector<identify::Oscillogram> records{line.record};
    identify::FitModel model(line.prior, records, line.config,
                             NoiseWeights(line.record, line.config));
    model.SetStage(1.0);
    const identify::FitOptions options;
    const int p = model.parameters();
    std::vector<double> truth(p);
    for (int i = 0; i < p; ++i) truth[i] = model.Unit(i, line.truth_values[i]);
    const identify::LocalFit minimum = identify::Refine(model, options, truth, true, 100);
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
    REQUIRE(Length(hop, minimum.u, minimum) == Approx(3.0).epsilon(0.05));

    const identify::LocalFit alone = identify::Refine(model, options, hop, true, 100);
    const identify::LocalFit back = identify::Refine(model, options, hop, true, 100, {}, &minimum);
    // Left alone the fit reaches the same minimum, within the rough floor of the misfit ...
    REQUIRE(alone.converged);
    CHECK_FALSE(alone.rejoined);
    CHECK(Length(alone.u, minimum.u, minimum) <= 0.3);
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
  }
}

}  // namespace millkit
