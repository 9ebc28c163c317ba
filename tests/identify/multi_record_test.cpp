// Several records of the same line fitted together (`millkit identify --data a.csv --data b.csv`):
// shared scene parameters, a bite time and a gain and offset per record and channel.
#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include "identify/fit_fixture.h"
#include "millkit/identify/fit.h"
#include "millkit/identify/fit_report.h"
#include "millkit/io/input_error.h"
#include "support/run_cli.h"

using namespace millkit::identify;
using namespace millkit::identify::testing;
using Catch::Matchers::Contains;

namespace {

// Two bites of the same line: the second one bites later on its recorder's clock.
constexpr double kSecondBite = 0.0612;

std::vector<Oscillogram> TwoBites(double noise, unsigned long seed, double lowpass_Hz = 0.0) {
  Oscillogram a = Mill5Record(noise, noise > 0.0 ? 12 : 0, lowpass_Hz, seed);
  Oscillogram b = Mill5Record(noise, noise > 0.0 ? 12 : 0, lowpass_Hz, seed + 1000,
                              {{"bite_time", kSecondBite}});
  a.source = "bite_a.csv";
  b.source = "bite_b.csv";
  return {a, b};
}

const ParameterEstimate& Named(const FitResult& fit, const std::string& name) {
  for (const auto& p : fit.parameters) {
    if (p.name == name) return p;
  }
  FAIL("no parameter " << name);
  throw;
}

// The factor the fit's warning says it widened a parameter's standard error by (1 when it
// names none; it names those above 1.05, to 3 digits).
double Widening(const FitResult& fit, const std::string& name) {
  const std::string lead = "standard errors widened where the cost is flatter";
  for (const auto& warning : fit.summary.warnings) {
    if (warning.rfind(lead, 0) != 0) continue;
    const size_t at = warning.find(" " + name + " x");
    if (at == std::string::npos) continue;
    return std::stod(warning.substr(at + name.size() + 3));
  }
  return 1.0;
}

}  // namespace

TEST_CASE("Two noise-free records give back the shared values and each record's bite time") {
  const auto records = TwoBites(0.0, 1);
  auto scene = Mill5Scene();
  const FitConfig config = Mill5Config(records, &scene);
  const FitResult fit = Fit(scene, records, config, FitOptions{});
  REQUIRE(fit.summary.success);
  // 8 shared link parameters + one bite time per record.
  REQUIRE(fit.parameters.size() == 10);
  for (const auto& p : fit.parameters) {
    INFO(p.name << " = " << p.value);
    const double truth = p.name == "bite_time@bite_a"   ? Mill5Truth().at("bite_time")
                         : p.name == "bite_time@bite_b" ? kSecondBite
                                                        : Mill5Truth().at(p.name);
    CHECK(std::abs(p.value - truth) <= 1e-6 * std::abs(truth));
    CHECK(p.record == (p.name.rfind("bite_time@", 0) == 0 ? p.name.substr(10) + ".csv" : ""));
  }
  // Gain and offset per record and channel, records one after another.
  REQUIRE(fit.channels.size() == 4);
  CHECK(fit.channels[2].record == "bite_b.csv");
  CHECK(fit.channels[2].record_label == "bite_b");
  CHECK(std::abs(fit.channels[3].gain - kLowerGain) <= 1e-6 * kLowerGain);
  CHECK(std::abs(fit.channels[3].offset - kLowerOffset) <= 1e-6 * std::abs(kLowerOffset));
  CHECK(fit.channels[2].time_s.size() == fit.channels[2].fitted.size());
  CHECK_THAT(fit.quantity_names.back(), Contains("offset.lower_spindle@bite_b"));
}

TEST_CASE("A second noisy record shrinks the shared standard errors by about 1/sqrt(2)") {
  const auto records = TwoBites(0.01, 7);
  auto scene_one = Mill5Scene();
  const FitConfig one = Mill5Config(records[0], &scene_one);
  const FitResult single = Fit(scene_one, records[0], one, FitOptions{});
  auto scene_two = Mill5Scene();
  const FitConfig two = Mill5Config(records, &scene_two);
  const FitResult both = Fit(scene_two, records, two, FitOptions{});
  REQUIRE(single.summary.success);
  REQUIRE(both.summary.success);
  for (const auto& p : single.parameters) {
    if (p.name == "bite_time") continue;
    // The linearised errors: a profile flatter than its linearisation widens an error, and
    // whatever is correlated with it, more on one record than on two.
    const double one = p.standard_error / Widening(single, p.name);
    const double two = Named(both, p.name).standard_error / Widening(both, p.name);
    const double ratio = two / one;
    INFO(p.name << ": linearised standard error " << one << " with one record, ratio " << ratio);
    // The second bite starts 7.5 ms later, so its window holds a little less of the response.
    CHECK(ratio > 0.6);
    CHECK(ratio < 0.85);
  }
}

TEST_CASE("Records fitted together must all hold every channel and the window") {
  auto records = TwoBites(0.0, 1);
  SECTION("a channel missing from the second record names that record") {
    records[1].channels[1] = "lower_torque";
    auto scene = Mill5Scene();
    CHECK_THROWS_WITH(Mill5Config(records, &scene),
                      Contains("lower_spindle") && Contains("bite_b.csv"));
  }
  SECTION("a window beyond the shorter record names it") {
    const int keep = 500;  // 0.25 s of the 0.4 s record, before the window's end at 0.3 s
    records[1].time_s.resize(keep);
    for (auto& column : records[1].values) column.resize(keep);
    millkit::testing::ScratchDir dir;
    const std::string config =
        "[fit]\nwindow = [0.0, 0.3]\n[[free]]\nname = \"bite_time\"\n"
        "[[channel]]\ncolumn = \"upper_spindle\"\n[[channel]]\ncolumn = \"lower_spindle\"\n";
    millkit::testing::WriteText(dir / "fit.toml", config);
    const auto scene = Mill5Scene();
    CHECK_THROWS_WITH(LoadFitConfig((dir / "fit.toml").string(), records, scene),
                      Contains("window") && Contains("bite_b.csv"));
  }
  SECTION("without a window the fit takes the span both records cover") {
    const int keep = 500;
    records[1].time_s.resize(keep);
    for (auto& column : records[1].values) column.resize(keep);
    const auto scene = Mill5Scene();
    const FitConfig config =
        LoadFitConfig(millkit::testing::SourcePath("datasets/records/mill5_two_spindles.fit.toml"),
                      records, scene);
    CHECK(config.window_start_s == 0.0);
    CHECK(config.window_end_s == records[1].time_s.back());
  }
}

TEST_CASE("identify takes --data more than once") {
  using namespace millkit::testing;
  ScratchDir dir;
  // The bundled config models the recorder's 800 Hz filter.
  const auto records = TwoBites(0.0, 1, 800.0);
  WriteText(dir / "bite_a.csv", FormatOscillogram(records[0]));
  WriteText(dir / "bite_b.csv", FormatOscillogram(records[1]));
  const auto result = RunMillkit(
      "identify '" + SourcePath("datasets/scenes/mill5_bite.toml") + "' --data '" +
      (dir / "bite_a.csv").string() + "' --data '" + (dir / "bite_b.csv").string() +
      "' --config '" + SourcePath("datasets/records/mill5_two_spindles.fit.toml") + "' --out '" +
      (dir / "fit.json").string() + "' --trace '" + (dir / "fit.csv").string() + "'");
  INFO(result.stderr_text);
  REQUIRE(result.exit_code == 0);
  const auto fit = nlohmann::json::parse(ReadText(dir / "fit.json"));
  CHECK(fit["records"].size() == 2);
  CHECK(fit["channels"].size() == 4);
  bool second_bite = false;
  for (const auto& p : fit["parameters"]) {
    if (p["name"] == "bite_time@bite_b") {
      second_bite = true;
      // Within 1 % of the filter's 0.2 ms delay (the generator filters its own fine grid as
      // linear between points; the model's filter is exact).
      CHECK(std::abs(p["value"].get<double>() - kSecondBite) <= 2e-6);
    }
  }
  CHECK(second_bite);
  const std::string trace = ReadText(dir / "fit.csv");
  CHECK(trace.rfind("record,time,upper_spindle.measured", 0) == 0);
  CHECK_THAT(trace, Contains("\nbite_b,"));
}

TEST_CASE("The same file given twice is two records in the trace") {
  FitResult result;
  for (const char* label : {"bite#1", "bite#2"}) {
    ChannelEstimate c;
    c.column = "upper_spindle";
    c.record = "bite.csv";
    c.record_label = label;
    c.time_s = {0.0, 0.001};
    c.measured = {1.0, 2.0};
    c.fitted = {1.5, 2.5};
    result.channels.push_back(c);
  }
  const std::string trace = FitTraceCsv(result);
  CHECK(trace.rfind("record,time,upper_spindle.measured,upper_spindle.fitted,"
                    "upper_spindle.residual\n",
                    0) == 0);
  CHECK_THAT(trace, Contains("\nbite#1,0.001,2,2.5,0.5\n"));
  CHECK_THAT(trace, Contains("\nbite#2,0,1,1.5,0.5\n"));
}
