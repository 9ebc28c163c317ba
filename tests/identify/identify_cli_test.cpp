// `millkit identify` and `millkit synthesize` on the command line: outputs, exit codes, no partial
// files.
#include <algorithm>
#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>
#include <regex>
#include <vector>

#include "identify/fit_fixture.h"
#include "millkit/driveline/scene.h"
#include "millkit/identify/oscillogram.h"
#include "millkit/identify/record_generator.h"
#include "millkit/io/number_format.h"
#include "support/run_cli.h"

using Catch::Matchers::Contains;
using millkit::testing::ReadText;
using millkit::testing::RunMillkit;
using millkit::testing::ScratchDir;
using millkit::testing::SourcePath;
using millkit::testing::WriteText;

namespace {

std::string Scene() { return "'" + SourcePath("datasets/scenes/mill5_bite.toml") + "'"; }
std::string Bundled(const std::string& name) {
  return "'" + SourcePath("datasets/records/" + name) + "'";
}

}  // namespace

TEST_CASE("identify fits the bundled record and writes JSON, trace and plot") {
  ScratchDir dir;
  const auto result = RunMillkit(
      "identify " + Scene() + " --data " + Bundled("mill5_two_spindles.csv") + " --config " +
      Bundled("mill5_two_spindles.fit.toml") + " --out '" + (dir / "fit.json").string() +
      "' --plot '" + (dir / "fit.svg").string() + "' --trace '" + (dir / "fit.csv").string() + "'");
  INFO(result.stderr_text);
  REQUIRE(result.exit_code == 0);
  const auto fit = nlohmann::json::parse(ReadText(dir / "fit.json"));
  CHECK(fit["success"] == true);
  CHECK(fit["parameters"].size() == 9);
  CHECK(fit["not_identifiable"].empty());
  // The truth of datasets/records/mill5_two_spindles.spec.toml within 4 standard errors.
  const auto& truth = millkit::identify::testing::Mill5Truth();
  for (const auto& p : fit["parameters"]) {
    INFO(p.dump());
    CHECK(std::abs(p["value"].get<double>() - truth.at(p["name"])) <=
          4.0 * p["standard_error"].get<double>());
  }
  CHECK(fit["correlation"]["matrix"].size() == 13);  // 9 parameters + 2 gains + 2 offsets
  CHECK_THAT(ReadText(dir / "fit.csv"), Contains("upper_spindle.measured,upper_spindle.fitted"));
  // The plot lists the fitted parameters with their standard errors, puts the fitted line over
  // the measured trace and scales the torque axis (the channels peak near 1e6 N*m).
  const std::string svg = ReadText(dir / "fit.svg");
  CHECK_THAT(svg, Contains("class=\"notes\""));
  for (const auto& p : fit["parameters"]) {
    const std::string name = p["name"];
    const std::string line =
        ">" + name + " = " +
        millkit::ValueWithError(p["value"].get<double>(), p["standard_error"].get<double>());
    CHECK_THAT(svg, Contains(line));
  }
  CHECK_THAT(svg, Contains(">verdict: ok"));
  CHECK_THAT(svg, Contains("stroke-opacity") && Contains("stroke-width=\"2.20\""));
  CHECK_THAT(svg, Contains("torque, kN\u00b7m") || Contains("torque, MN\u00b7m"));
  CHECK_FALSE(std::regex_search(svg, std::regex("[0-9]{8}")));  // no 16-digit numbers anywhere
  CHECK_THAT(result.stdout_text, Contains("upper_spindle.backlash"));
}

TEST_CASE("identify reports a gap the record cannot tell with a null standard error") {
  ScratchDir dir;
  const auto result = RunMillkit(
      "identify " + Scene() + " --data " + Bundled("mill5_balanced_lower.csv") + " --config " +
      Bundled("mill5_balanced_lower.fit.toml") + " --out '" + (dir / "fit.json").string() + "'");
  INFO(result.stderr_text);
  REQUIRE(result.exit_code == 0);
  const auto fit = nlohmann::json::parse(ReadText(dir / "fit.json"));
  REQUIRE(fit["not_identifiable"].size() == 1);
  CHECK(fit["not_identifiable"][0]["name"] == "lower_spindle.backlash");
  for (const auto& p : fit["parameters"]) {
    if (p["name"] == "lower_spindle.backlash") CHECK(p["standard_error"].is_null());
  }
  CHECK_THAT(result.stdout_text, Contains("NOT IDENTIFIABLE"));
}

TEST_CASE("identify rejects bad input with exit 2 and leaves no output behind") {
  ScratchDir dir;
  const std::string out =
      " --out '" + (dir / "fit.json").string() + "' --plot '" + (dir / "fit.svg").string() + "'";
  WriteText(dir / "bad.csv", "time,upper_spindle\n0,1\n0.001,x\n");
  const auto bad_cell =
      RunMillkit("identify " + Scene() + " --data '" + (dir / "bad.csv").string() + "'" + out);
  CHECK(bad_cell.exit_code == 2);
  CHECK_THAT(bad_cell.stderr_text, Contains("bad.csv") && Contains("line 3"));
  WriteText(dir / "fit.toml", "[[free]]\nname = \"upper_spindle.colour\"\nlower = 0\nupper = 1\n");
  const auto bad_name =
      RunMillkit("identify " + Scene() + " --data " + Bundled("mill5_two_spindles.csv") +
                 " --config '" + (dir / "fit.toml").string() + "'" + out);
  CHECK(bad_name.exit_code == 2);
  CHECK_THAT(bad_name.stderr_text, Contains("fit.toml") && Contains("upper_spindle.colour"));
  CHECK(dir.EntryCount() == 2);  // only the two inputs written above
}

TEST_CASE("synthesize writes the bundled record again, to within one ADC step") {
  // Not bit for bit: a solver change moves the exact solution by roundoff (~1e-12 of peak), which
  // moves the quantiser's step (it follows the measured peak) by roundoff and can flip the level
  // of a sample that sits on a step boundary.
  ScratchDir dir;
  const auto result =
      RunMillkit("synthesize " + Scene() + " --spec " + Bundled("mill5_two_spindles.spec.toml") +
                 " --out '" + (dir / "rec.csv").string() + "'");
  INFO(result.stderr_text);
  REQUIRE(result.exit_code == 0);
  const auto made = millkit::identify::LoadOscillogram(dir / "rec.csv");
  const auto bundled =
      millkit::identify::LoadOscillogram(SourcePath("datasets/records/mill5_two_spindles.csv"));
  REQUIRE(made.time_s == bundled.time_s);
  REQUIRE(made.channels == bundled.channels);
  for (size_t c = 0; c < made.channels.size(); ++c) {
    double peak = 0.0;
    for (double v : bundled.values[c]) peak = std::max(peak, std::abs(v));
    const double adc_step = 2.0 * 1.5 * peak / 4096.0;  // the spec's 12 bits over ±1.5 × peak
    int differing = 0;
    for (size_t k = 0; k < made.time_s.size(); ++k) {
      const double difference = std::abs(made.values[c][k] - bundled.values[c][k]);
      CHECK(difference <= 1.01 * adc_step);
      differing += difference > 0.5 * adc_step ? 1 : 0;  // a flipped quantiser level
    }
    CHECK(differing <= 2);
  }
}

TEST_CASE("The record generator reports its progress up to the end and the record is unchanged") {
  auto scene = millkit::driveline::LoadScene(SourcePath("datasets/scenes/mill5_bite.toml"));
  const auto spec = millkit::identify::LoadRecordSpec(
      SourcePath("datasets/records/mill5_two_spindles.spec.toml"), &scene);
  std::vector<double> fractions;
  const auto with = millkit::identify::GenerateRecord(
      scene, spec, [&fractions](double f) { fractions.push_back(f); });
  const auto without = millkit::identify::GenerateRecord(scene, spec);
  // The spec's 0.4 s at 2 kHz, simulated 16 times finer: 800 · 16 + 1 samples.
  CHECK(fractions.size() == 800 * 16 + 1);
  CHECK(std::is_sorted(fractions.begin(), fractions.end()));
  CHECK(fractions.back() == 1.0);
  CHECK(with.time_s == without.time_s);
  CHECK(with.values == without.values);
}
