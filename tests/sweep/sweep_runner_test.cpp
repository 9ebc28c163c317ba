// The threaded case runner: order, determinism, failed cases, errors, progress.
#include "millkit/sweep/sweep_runner.h"

#include <catch2/catch.hpp>
#include <chrono>
#include <sstream>
#include <stdexcept>
#include <thread>
#include <tuple>

#include "millkit/io/input_error.h"
#include "millkit/sweep/sweep_table.h"
#include "support/study_support.h"
#include "sweep/study_input.h"

using namespace millkit::sweep;
using Catch::Matchers::Contains;
using millkit::driveline::LoadScene;
using millkit::driveline::ParseSceneParameter;
using millkit::driveline::Scene;
using millkit::testing::ReadText;
using millkit::testing::ScratchDir;
using millkit::testing::SourcePath;
using millkit::testing::WriteText;

namespace {

const Scene& Mill5() { return millkit::testing::Mill5Scene(); }

SweepConfig Mill5Lhs(int samples) {
  SweepConfig config;
  config.method = SweepConfig::Method::kLatinHypercube;
  config.samples = samples;
  config.seed = 11;
  config.links = AllLinks(Mill5());
  for (auto [name, lo, hi] : {std::tuple{"upper_spindle.damping", 1000.0, 20000.0},
                              std::tuple{"lower_spindle.backlash", 0.0, 0.04},
                              std::tuple{"main_coupling.gap_position", -1.0, 1.0}}) {
    SweepDimension d;
    d.parameter = ParseSceneParameter(Mill5(), name, "test");
    d.lower = lo;
    d.upper = hi;
    config.dimensions.push_back(d);
  }
  return config;
}

std::string RunToCsv(const SweepConfig& config, int threads) {
  RunnerOptions options;
  options.threads = threads;
  const CaseList cases = config.Cases();
  const auto results = RunCases(
      SceneCaseFunction(Mill5(), config.Parameters(), StudySimulationOptions()), cases, options);
  return FormatSweepCsv(Mill5(), config, cases, results);
}

}  // namespace

TEST_CASE("sweep rows are bitwise identical for 1 and 3 threads", "[sweep][runner]") {
  const SweepConfig config = Mill5Lhs(24);
  const std::string serial = RunToCsv(config, 1);
  CHECK(RunToCsv(config, 3) == serial);
  CHECK(std::count(serial.begin(), serial.end(), '\n') == 25);
  CHECK(serial.find(",failed,") == std::string::npos);
}

TEST_CASE("a sweep case gives the same Kd as the scene file written with that value",
          "[sweep][runner]") {
  // Independent path: edit the TOML text, load it, simulate; no SceneParameter involved.
  ScratchDir dir;
  std::string text = ReadText(SourcePath("datasets/scenes/mill5_bite.toml"));
  const std::string from = "stiffness = 1.2e7\ndamping = 5000.0";  // upper_spindle
  REQUIRE(text.find(from) != std::string::npos);
  text.replace(text.find(from), from.size(), "stiffness = 1.2e7\ndamping = 7250.5");
  WriteText(dir / "edited.toml", text);
  const CaseResult reference =
      SimulateCase(LoadScene((dir / "edited.toml").string()), StudySimulationOptions());
  REQUIRE(reference.success);

  const auto damping = ParseSceneParameter(Mill5(), "upper_spindle.damping", "test");
  const auto results = RunCases(SceneCaseFunction(Mill5(), {damping}, StudySimulationOptions()),
                                {{5000.0}, {7250.5}}, RunnerOptions{});
  REQUIRE(results[1].success);
  CHECK(results[1].kd == reference.kd);
  CHECK(results[1].peak_torque_Nm == reference.peak_torque_Nm);
  CHECK(results[1].events == reference.events);
  CHECK(results[0].kd != reference.kd);
}

TEST_CASE("a case that cannot run is reported in its row and the sweep goes on",
          "[sweep][runner]") {
  // 1e12 N*m/rad puts the upper spindle's mode far above what 5 kHz sampling resolves: the
  // scene is invalid at that value (the model refuses it), the neighbours are fine.
  const auto stiffness = ParseSceneParameter(Mill5(), "upper_spindle.stiffness", "test");
  RunnerOptions options;
  options.threads = 2;
  RunnerSummary summary;
  const auto results = RunCases(SceneCaseFunction(Mill5(), {stiffness}, StudySimulationOptions()),
                                {{1.2e7}, {1e12}, {1.0e7}}, options, &summary);
  CHECK(results[0].success);
  CHECK_FALSE(results[1].success);
  CHECK_THAT(results[1].message, Contains("sample_rate"));
  CHECK(results[2].success);
  CHECK(summary.failed == 1);
  CHECK(summary.cases == 3);
}

TEST_CASE("an unexpected error in a case stops the pool and is rethrown", "[sweep][runner]") {
  RunnerOptions options;
  options.threads = 3;
  CaseList cases(50, std::vector<double>{0.0});
  cases[7][0] = 1.0;
  const CaseFunction evaluate = [](const std::vector<double>& v) {
    if (v[0] == 1.0) throw std::runtime_error("broken invariant in case");
    CaseResult r;
    r.success = true;
    return r;
  };
  CHECK_THROWS_WITH(RunCases(evaluate, cases, options), Contains("broken invariant"));
}

TEST_CASE("a long run prints a progress line, a short one prints nothing", "[sweep][runner]") {
  const CaseFunction slow = [](const std::vector<double>&) {
    std::this_thread::sleep_for(std::chrono::milliseconds(150));
    CaseResult r;
    r.success = true;
    return r;
  };
  std::ostringstream progress;
  RunnerOptions options;
  options.progress = &progress;
  RunCases(slow, CaseList(10, std::vector<double>{0.0}), options);
  CHECK_THAT(progress.str(), Contains("sweep: ") && Contains("10/10 cases, 0 failed"));
  std::ostringstream quiet;
  options.progress = &quiet;
  RunCases(slow, CaseList(2, std::vector<double>{0.0}), options);
  CHECK(quiet.str().empty());
}

TEST_CASE("the runner refuses a thread count outside [1, 256]", "[sweep][runner][bad_input]") {
  RunnerOptions options;
  options.threads = 0;
  CHECK_THROWS_AS(options.Validate(), millkit::InputError);
  options.threads = 257;
  CHECK_THROWS_AS(options.Validate(), millkit::InputError);
}
