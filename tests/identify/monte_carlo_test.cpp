// Monte Carlo over noisy records (issue 3): the reported standard errors are honest.
#include <catch2/catch.hpp>
#include <cmath>
#include <vector>

#include "identify/fit_fixture.h"
#include "millkit/identify/fit.h"

using namespace millkit::identify;
using namespace millkit::identify::testing;

namespace {

constexpr int kSeeds = 20;             // issue 3: >= 20 seeds
constexpr double kCoverage = 0.90;     // truth within ±3 SE in >= 90 % of fits
constexpr double kSpreadFactor = 1.5;  // observed spread vs reported SE within this factor

}  // namespace

TEST_CASE(
    "Over 20 noisy records the truth lies within 3 standard errors and the errors match "
    "the spread") {
  // 1 % noise, 12-bit ADC, gain and offset errors; no filter (a known filter is modelled, see
  // fit_recovery_test). Starts: the scene's nominal values (10–25 % off the truth). Window: the
  // bundled config's, the whole 0.4 s record.
  std::vector<std::vector<double>> errors;  // [parameter][seed]
  std::vector<std::vector<double>> standard_errors;
  std::vector<std::string> names;
  int inside = 0;
  int total = 0;
  for (int seed = 1; seed <= kSeeds; ++seed) {
    const Oscillogram record = Mill5Record(0.01, 12, 0.0, 1000 + seed);
    auto scene = Mill5Scene();
    FitConfig config = Mill5Config(record, &scene, 0.0, /*window_end_s=*/0.0);
    // The bundled config's robust start: from the nominal start alone, 1 record in 20 ended in a
    // local minimum (seed 1014: cost 0.0630 against 0.0587 from the truth; measured on a window
    // ending at 0.3 s, before issue 12's search).
    config.scan_points = 32;
    config.starts = 2;
    const FitResult fit = Fit(scene, record, config, FitOptions{});
    REQUIRE(fit.summary.success);
    if (names.empty()) {
      for (const auto& p : fit.parameters) names.push_back(p.name);
      errors.resize(names.size());
      standard_errors.resize(names.size());
    }
    for (size_t i = 0; i < fit.parameters.size(); ++i) {
      const auto& p = fit.parameters[i];
      REQUIRE(p.identifiable);
      const double error = p.value - Mill5Truth().at(p.name);
      errors[i].push_back(error);
      standard_errors[i].push_back(p.standard_error);
      inside += std::abs(error) <= 3.0 * p.standard_error ? 1 : 0;
      ++total;
    }
  }
  const double coverage = static_cast<double>(inside) / total;
  INFO("coverage " << coverage);
  CHECK(coverage >= kCoverage);
  for (size_t i = 0; i < names.size(); ++i) {
    double mean = 0.0;
    double mean_se = 0.0;
    for (int k = 0; k < kSeeds; ++k) {
      mean += errors[i][k] / kSeeds;
      mean_se += standard_errors[i][k] / kSeeds;
    }
    double variance = 0.0;
    for (int k = 0; k < kSeeds; ++k) variance += std::pow(errors[i][k] - mean, 2) / (kSeeds - 1);
    const double ratio = std::sqrt(variance) / mean_se;
    INFO(names[i] << ": observed spread / reported standard error = " << ratio);
    CHECK(ratio <= kSpreadFactor);
    CHECK(ratio >= 1.0 / kSpreadFactor);
  }
}
