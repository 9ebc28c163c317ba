// SimulationOptions::output_times, keep_samples, sample_sink and progress (issues 2, 13): sampling
// on a grid unrelated to the scene's, the Kd-only fast path, and streaming a run sample by sample.
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>

#include "millkit/driveline/simulation.h"
#include "millkit/io/input_error.h"
#include "scene_builder.h"
#include "support/run_cli.h"

using namespace millkit::driveline;
using Catch::Matchers::Contains;
using millkit::driveline::testing::RelativeDifference;

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

namespace {
// A copy of each sample the sink receives, as rows of the result matrices.
struct SinkCopy {
  std::vector<double> time_s;
  std::vector<int> index;
  std::vector<std::vector<double>> torque, speed, twist;
};

std::function<void(const OutputSample&)> CopyTo(SinkCopy* copy, const Scene& scene) {
  const size_t links = scene.links.size(), masses = scene.masses.size();
  return [copy, links, masses](const OutputSample& s) {
    copy->index.push_back(s.index);
    copy->time_s.push_back(s.time_s);
    copy->torque.emplace_back(s.link_torque_Nm, s.link_torque_Nm + links);
    copy->speed.emplace_back(s.mass_speed_rad_per_s, s.mass_speed_rad_per_s + masses);
    copy->twist.emplace_back(s.link_twist_rad, s.link_twist_rad + links);
  };
}

bool RowsEqual(const SampleMatrix& matrix, const std::vector<std::vector<double>>& rows) {
  if (static_cast<size_t>(matrix.rows()) != rows.size()) return false;
  for (int k = 0; k < matrix.rows(); ++k) {
    for (int j = 0; j < matrix.cols(); ++j) {
      if (matrix(k, j) != rows[k][j]) return false;
    }
  }
  return true;
}

// The five-mass bite, and a geared two-mass line whose outputs are converted per shaft.
std::vector<Scene> SinkScenes() {
  Scene geared = testing::TwoMassScene(50.0, 20.0, 1.0e5, 20.0, 0.01, 0.2, 4000.0);
  geared.links[0].ratio = 3.0;
  geared.initial_speed_rad_per_s = 5.0;
  geared.torques = {testing::Step(1, 0.0, -3000.0, 0.02, 0.005),
                    testing::Step(0, 0.0, 200.0, 0.05, 0.0)};
  return {FiveMass().scene(), geared};
}
}  // namespace

TEST_CASE(
    "A sample sink without kept samples receives every sample exactly as the matrices hold it",
    "[output][stream]") {
  for (const Scene& scene : SinkScenes()) {
    const Model model(scene);
    for (auto solver : {SolverKind::kExact, SolverKind::kCvode}) {
      SimulationOptions options;
      options.solver = solver;
      const auto kept = Simulate(model, options);
      SinkCopy copy;
      options.keep_samples = false;
      options.sample_sink = CopyTo(&copy, model.scene());
      const auto streamed = Simulate(model, options);
      REQUIRE(kept.summary.success);
      REQUIRE(streamed.summary.success);
      CHECK(streamed.link_torque_Nm.size() == 0);
      REQUIRE(copy.time_s.size() == kept.time_s.size());
      for (size_t k = 0; k < copy.index.size(); ++k) REQUIRE(copy.index[k] == static_cast<int>(k));
      CHECK(copy.time_s == kept.time_s);
      CHECK(RowsEqual(kept.link_torque_Nm, copy.torque));
      CHECK(RowsEqual(kept.mass_speed_rad_per_s, copy.speed));
      CHECK(RowsEqual(kept.link_twist_rad, copy.twist));
    }
  }
}

TEST_CASE("Kd is bit-identical whether samples are kept, streamed or neither", "[output][stream]") {
  for (const Scene& scene : SinkScenes()) {
    const Model model(scene);
    for (auto solver : {SolverKind::kExact, SolverKind::kCvode}) {
      SimulationOptions options;
      options.solver = solver;
      const auto plain = DynamicFactors(model, Simulate(model, options));
      SinkCopy copy;
      options.sample_sink = CopyTo(&copy, model.scene());
      options.progress = [](double) {};
      const auto kept_and_streamed = DynamicFactors(model, Simulate(model, options));
      options.keep_samples = false;
      const auto streamed = DynamicFactors(model, Simulate(model, options));
      options.sample_sink = nullptr;
      const auto peaks_only = DynamicFactors(model, Simulate(model, options));
      for (const auto* other : {&kept_and_streamed, &streamed, &peaks_only}) {
        REQUIRE(other->size() == plain.size());
        for (size_t l = 0; l < plain.size(); ++l) {
          CHECK(std::memcmp(&(*other)[l].kd, &plain[l].kd, sizeof(double)) == 0);
          CHECK((*other)[l].peak_torque_Nm == plain[l].peak_torque_Nm);
          CHECK((*other)[l].peak_time_s == plain[l].peak_time_s);
        }
      }
    }
  }
}

TEST_CASE("Progress rises once per output sample to 1, over both runs of a checked CVODE run",
          "[output][stream]") {
  const Model model = FiveMass();
  const int samples = model.scene().SampleCount();
  SimulationOptions options;
  std::vector<double> fractions;
  options.progress = [&fractions](double f) { fractions.push_back(f); };
  REQUIRE(Simulate(model, options).summary.success);
  REQUIRE(fractions.size() == static_cast<size_t>(samples));
  CHECK(std::is_sorted(fractions.begin(), fractions.end()));
  CHECK(fractions.front() > 0.0);
  CHECK(fractions.back() == 1.0);

  fractions.clear();
  options.solver = SolverKind::kCvode;
  int streamed = 0;
  options.sample_sink = [&streamed](const OutputSample&) { ++streamed; };
  REQUIRE(SimulateCvodeChecked(model, options).summary.success);
  CHECK(streamed == samples);  // the check run streams nothing
  REQUIRE(fractions.size() == static_cast<size_t>(2 * samples));
  CHECK(std::is_sorted(fractions.begin(), fractions.end()));
  CHECK(fractions[samples - 1] == 0.5);
  CHECK(fractions.back() == 1.0);
}

TEST_CASE("An exception thrown by the sample sink ends the run and leaves both solvers",
          "[output][stream]") {
  const Model model = FiveMass();
  for (auto solver : {SolverKind::kExact, SolverKind::kCvode}) {
    SimulationOptions options;
    options.solver = solver;
    options.keep_samples = false;
    int calls = 0;
    options.sample_sink = [&calls](const OutputSample& sample) {
      ++calls;
      if (sample.index == 10) throw millkit::InputError("disk full");
    };
    CHECK_THROWS_WITH(Simulate(model, options), Contains("disk full"));
    CHECK(calls == 11);
  }
}
