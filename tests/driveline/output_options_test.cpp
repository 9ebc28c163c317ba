// SimulationOptions::output_times and keep_samples (issue 2): sampling on a grid unrelated to the
// scene's, and the Kd-only fast path.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <limits>

#include "driveline/simulation.h"
#include "io/input_error.h"
#include "scene_builder.h"
#include "support/run_cli.h"

using namespace millkit::driveline;
using millkit::driveline::testing::RelativeDifference;
using Catch::Matchers::Contains;

namespace {
Model FiveMass() {
  return Model(LoadScene(millkit::testing::SourcePath("datasets/scenes/mill5_bite.toml")));
}

// A non-uniform grid shifted off the scene's 5 kHz grid (gaps cycling 0.07, 0.13, 0.31 ms, as an
// irregular logger would give), merged with every 7th scene sample time up to `end` so that the
// two grids coincide there.
std::vector<double> MixedGrid(const std::vector<double>& scene_times, double end) {
  std::vector<double> times;
  const double gaps[] = {0.7e-4, 1.3e-4, 3.1e-4};
  for (double t = 0.37e-4; t <= end; t += gaps[times.size() % 3]) times.push_back(t);
  for (size_t k = 0; k < scene_times.size() && scene_times[k] <= end; k += 7) {
    times.push_back(scene_times[k]);
  }
  std::sort(times.begin(), times.end());
  times.erase(std::unique(times.begin(), times.end()), times.end());
  return times;
}

// Rows of `result` at the times that also appear in `grid` (exactly), and the matching rows of
// the scene-grid run.
void Coinciding(const SimulationResult& result, const SimulationResult& on_scene_grid,
                SampleMatrix* a, SampleMatrix* b) {
  std::vector<std::pair<int, int>> rows;
  for (size_t i = 0, j = 0; i < result.time_s.size() && j < on_scene_grid.time_s.size();) {
    if (result.time_s[i] == on_scene_grid.time_s[j]) {
      rows.push_back({static_cast<int>(i++), static_cast<int>(j++)});
    } else if (result.time_s[i] < on_scene_grid.time_s[j]) {
      ++i;
    } else {
      ++j;
    }
  }
  a->resize(static_cast<int>(rows.size()), result.link_torque_Nm.cols());
  b->resize(static_cast<int>(rows.size()), result.link_torque_Nm.cols());
  for (size_t r = 0; r < rows.size(); ++r) {
    a->row(static_cast<int>(r)) = result.link_torque_Nm.row(rows[r].first);
    b->row(static_cast<int>(r)) = on_scene_grid.link_torque_Nm.row(rows[r].second);
  }
}
}  // namespace

TEST_CASE("Output times off the scene grid give the scene-grid values where the grids coincide",
          "[output]") {
  // Both runs are exact to roundoff; only the propagation path differs (Taylor action against
  // the cached step exponential). Roundoff in the event times, carried through 86 impacts, makes
  // them differ by 1.1e-11 of peak; the check asks for a tenth of the 1e-9 the solver claims.
  constexpr double kSamePathTolerance = 1e-10;
  const Model model = FiveMass();
  const auto on_scene_grid = Simulate(model, {});
  SimulationOptions options;
  options.output_times = MixedGrid(on_scene_grid.time_s, model.scene().duration_s);
  const auto result = Simulate(model, options);
  REQUIRE(result.summary.success);
  CHECK(result.time_s == *options.output_times);
  REQUIRE(result.link_torque_Nm.rows() == static_cast<int>(options.output_times->size()));
  SampleMatrix a, b;
  Coinciding(result, on_scene_grid, &a, &b);
  REQUIRE(a.rows() > 300);
  CHECK(RelativeDifference(a, b) <= kSamePathTolerance);
}

TEST_CASE("On output times off the scene grid the exact solver agrees with CVODE", "[output]") {
  // As in solver_agreement_test: CVODE at rtol 1e-12 agrees with the exact solver to 1e-7.
  const Model model = FiveMass();
  SimulationOptions options;
  options.output_times = MixedGrid(Simulate(model, {}).time_s, model.scene().duration_s);
  const auto exact = Simulate(model, options);
  options.solver = SolverKind::kCvode;
  options.rtol = 1e-12;
  const auto cvode = Simulate(model, options);
  REQUIRE(exact.summary.success);
  REQUIRE(cvode.summary.success);
  CHECK(cvode.time_s == *options.output_times);
  CHECK(RelativeDifference(cvode.link_torque_Nm, exact.link_torque_Nm) <= 1e-7);
}

TEST_CASE("A run with output times ends at the last one and simulates no event after it",
          "[output]") {
  const Model model = FiveMass();
  // A uniform 10 kHz grid shifted off the scene's, over the whole scene and cut at 0.1 s (after
  // the bite, before the end).
  std::vector<double> whole, cut;
  for (int k = 0; 0.25e-4 + k * 1e-4 <= model.scene().duration_s; ++k) {
    whole.push_back(0.25e-4 + k * 1e-4);
    if (k <= 1000) cut.push_back(whole.back());
  }
  for (auto solver : {SolverKind::kExact, SolverKind::kCvode}) {
    SimulationOptions options;
    options.solver = solver;
    options.rtol = 1e-12;
    options.output_times = whole;
    const auto full = Simulate(model, options);
    options.output_times = cut;
    const auto result = Simulate(model, options);
    REQUIRE(full.summary.success);
    REQUIRE(result.summary.success);
    REQUIRE(!result.summary.event_times_s.empty());
    CHECK(result.summary.event_times_s.back() <= cut.back());
    CHECK(result.summary.events < full.summary.events);
    if (solver == SolverKind::kExact) {
      // Up to the cut the two runs see the same events. Their times agree to roundoff only: the
      // cached step is each grid's median gap, which differs in the last bits between the grids.
      constexpr double kEventTimeRoundoff_s = 1e-10;
      const std::vector<double> before_cut(
          full.summary.event_times_s.begin(),
          std::upper_bound(full.summary.event_times_s.begin(), full.summary.event_times_s.end(),
                           cut.back()));
      REQUIRE(result.summary.event_times_s.size() == before_cut.size());
      for (size_t i = 0; i < before_cut.size(); ++i) {
        CHECK_THAT(result.summary.event_times_s[i],
                   Catch::Matchers::WithinAbs(before_cut[i], kEventTimeRoundoff_s));
      }
    }
  }
}

TEST_CASE("Bad output times are rejected naming the rule", "[output]") {
  const Model model = FiveMass();
  const double inf = std::numeric_limits<double>::infinity();
  const std::vector<std::pair<std::vector<double>, std::string>> cases = {
      {{}, "must not be empty"},
      {{0.0, 0.1, 0.1}, "strictly increasing"},
      {{0.0, 0.2, 0.1}, "strictly increasing"},
      {{-1e-3, 0.1}, "must be >= 0"},
      {{0.0, std::nan(""), 0.2}, "must be finite"},
      {{0.0, inf}, "must be finite"},
      {{0.0, 0.25, 0.5000001}, "scene duration"},
  };
  for (const auto& [times, rule] : cases) {
    SimulationOptions options;
    options.output_times = times;
    for (auto solver : {SolverKind::kExact, SolverKind::kCvode}) {
      options.solver = solver;
      CHECK_THROWS_WITH(Simulate(model, options), Contains("output_times") && Contains(rule));
    }
  }
}

TEST_CASE("Without kept samples the result has no samples and the same Kd", "[output]") {
  const Model model = FiveMass();
  for (auto solver : {SolverKind::kExact, SolverKind::kCvode}) {
    SimulationOptions options;
    options.solver = solver;
    const auto kept = Simulate(model, options);
    options.keep_samples = false;
    const auto peaks_only = Simulate(model, options);
    REQUIRE(kept.summary.success);
    REQUIRE(peaks_only.summary.success);
    CHECK(peaks_only.time_s.empty());
    CHECK(peaks_only.link_torque_Nm.size() == 0);
    CHECK(peaks_only.mass_speed_rad_per_s.size() == 0);
    CHECK(peaks_only.link_twist_rad.size() == 0);
    const auto with = DynamicFactors(model, kept);
    const auto without = DynamicFactors(model, peaks_only);
    REQUIRE(with.size() == without.size());
    for (size_t l = 0; l < with.size(); ++l) {
      CHECK(with[l].kd == without[l].kd);
      CHECK(with[l].peak_torque_Nm == without[l].peak_torque_Nm);
      CHECK(with[l].peak_time_s == without[l].peak_time_s);
      CHECK(with[l].kd > 1.0);  // a bite through open gaps overshoots the static torque
    }
  }
}

TEST_CASE("The peak fields are the max |torque| over the kept samples and its first time",
          "[output]") {
  const Model model = FiveMass();
  const auto result = Simulate(model, {});
  REQUIRE(result.peak_abs_torque_Nm.size() == model.scene().links.size());
  for (int l = 0; l < result.link_torque_Nm.cols(); ++l) {
    Eigen::Index at = 0;
    const double peak = result.link_torque_Nm.col(l).cwiseAbs().maxCoeff(&at);
    CHECK(result.peak_abs_torque_Nm[l] == peak);
    CHECK(result.peak_time_s[l] == result.time_s[at]);
  }
}
