// Fit configs: every rule of include/millkit/identify/fit_config.h names the file and key.
#include "millkit/identify/fit_config.h"

#include <catch2/catch.hpp>

#include "identify/fit_fixture.h"
#include "millkit/identify/fit_report.h"
#include "millkit/io/input_error.h"
#include "support/run_cli.h"

using namespace millkit::identify;
using namespace millkit::identify::testing;
using Catch::Matchers::Contains;
using millkit::InputError;
using millkit::testing::ScratchDir;
using millkit::testing::WriteText;

namespace {

const char* kFree = R"(
[[free]]
name = "upper_spindle.damping"
lower = 500.0
upper = 30000.0
[[channel]]
column = "upper_spindle"
)";

// Loads `text` as a fit config against the noise-free five-mass record.
FitConfig Load(const std::string& text) {
  static const Oscillogram record = Mill5Record(0.0, 0, 0.0, 1);
  ScratchDir dir;
  WriteText(dir / "fit.toml", text);
  auto scene = Mill5Scene();
  return LoadFitConfig((dir / "fit.toml").string(), record, scene);
}

}  // namespace

TEST_CASE("A fit config loads its window, parameters and channels") {
  const FitConfig config = Load(std::string("[fit]\nwindow = [0.01, 0.3]\nstarts = 3\n") + kFree);
  CHECK(config.window_start_s == 0.01);
  CHECK(config.window_end_s == 0.3);
  CHECK(config.starts == 3);
  REQUIRE(config.free.size() == 1);
  CHECK(config.free[0].start == 5000.0);  // the scene's value
  REQUIRE(config.channels.size() == 1);
  CHECK(config.channels[0].link == "upper_spindle");
  CHECK(config.channels[0].fit_gain);
}

TEST_CASE("An unknown parameter name is rejected naming the key") {
  CHECK_THROWS_WITH(
      Load("[[free]]\nname = \"upper_spindle.colour\"\nlower = 0\nupper = 1\n"),
      Contains("fit.toml") && Contains("upper_spindle.colour") && Contains("key 'name'"));
}

TEST_CASE("Bounds with lower above upper are rejected") {
  CHECK_THROWS_WITH(Load("[[free]]\nname = \"upper_spindle.damping\"\nlower = 9000\nupper = 100\n"
                         "start = 5000\n[[channel]]\ncolumn = \"upper_spindle\"\n"),
                    Contains("[[free]] #1") && Contains("must be below upper bound"));
}

TEST_CASE("A start outside its bounds is rejected") {
  CHECK_THROWS_WITH(Load("[[free]]\nname = \"upper_spindle.damping\"\nlower = 100\nupper = 900\n"
                         "[[channel]]\ncolumn = \"upper_spindle\"\n"),
                    Contains("start 5000 lies outside its bounds"));
}

TEST_CASE("Bounds outside the physical range are rejected") {
  CHECK_THROWS_WITH(Load("[[free]]\nname = \"upper_spindle.backlash\"\nlower = -0.01\nupper = 0.1\n"
                         "[[channel]]\ncolumn = \"upper_spindle\"\n"),
                    Contains("physical range"));
}

TEST_CASE("A window outside the record is rejected") {
  CHECK_THROWS_WITH(Load(std::string("[fit]\nwindow = [0.1, 0.9]\n") + kFree),
                    Contains("key 'window'") && Contains("inside the record"));
  CHECK_THROWS_WITH(Load(std::string("[fit]\nwindow = [0.3, 0.1]\n") + kFree),
                    Contains("key 'window'"));
}

TEST_CASE("A channel column missing from the record is rejected") {
  CHECK_THROWS_WITH(Load("[[free]]\nname = \"upper_spindle.damping\"\nlower = 100\nupper = 9e4\n"
                         "[[channel]]\ncolumn = \"motor_torque\"\n"),
                    Contains("key 'column'") && Contains("no column 'motor_torque'"));
}

TEST_CASE("Unknown keys, unknown links and repeated parameters are rejected") {
  CHECK_THROWS_WITH(Load(std::string("[fit]\nwindows = [0, 1]\n") + kFree),
                    Contains("unknown key"));
  CHECK_THROWS_WITH(Load("[[free]]\nname = \"upper_spindle.damping\"\nlower = 100\nupper = 9e4\n"
                         "[[channel]]\ncolumn = \"upper_spindle\"\nlink = \"axle\"\n"),
                    Contains("no link named 'axle'"));
  CHECK_THROWS_WITH(Load(std::string(kFree) + "[[free]]\nname = \"upper_spindle.damping\"\n"
                                              "lower = 100\nupper = 9e4\n"),
                    Contains("listed twice"));
}

TEST_CASE("A [set] value outside the physical range is rejected") {
  CHECK_THROWS_WITH(Load(std::string("[set]\n\"lower_spindle.gap_position\" = 3.0\n") + kFree),
                    Contains("[set]") || Contains("physical range"));
}

TEST_CASE("Without a config every column named like a link is fitted with its damping and gap") {
  const Oscillogram record = Mill5Record(0.0, 0, 0.0, 1);
  const auto scene = Mill5Scene();
  const FitConfig config = DefaultFitConfig(scene, record);
  CHECK(config.channels.size() == 2);
  // 4 dampings + 3 backlashes + bite_time.
  CHECK(config.free.size() == 8);
}

TEST_CASE("channel units: the config's unit, the units row's, and their agreement") {
  CHECK(ParseTorqueUnit("N*m")->newton_metres == 1.0);
  CHECK(ParseTorqueUnit("[kNm]")->name == "kN*m");
  CHECK(ParseTorqueUnit("kN\xC2\xB7m")->newton_metres == 1e3);
  CHECK(ParseTorqueUnit("MN.m")->newton_metres == 1e6);
  CHECK_FALSE(ParseTorqueUnit("rpm"));
  CHECK_FALSE(ParseTorqueUnit("mNm"));

  const std::string free =
      "[[free]]\nname = \"upper_spindle.damping\"\nlower = 500.0\n"
      "upper = 30000.0\n";
  SECTION("unit in the config converts weight and offset_limit to N*m") {
    const FitConfig config = Load(free +
                                  "[[channel]]\ncolumn = \"upper_spindle\"\nunit = \"kN*m\"\n"
                                  "weight = 2.0\noffset_limit = 5.0\n");
    CHECK(config.channels[0].unit.name == "kN*m");
    CHECK(*config.channels[0].weight == 2.0e-3);
    CHECK(*config.channels[0].offset_limit_Nm == 5.0e3);
  }
  SECTION("an unknown unit names the key") {
    CHECK_THROWS_WITH(Load(free + "[[channel]]\ncolumn = \"upper_spindle\"\nunit = \"lbf*ft\"\n"),
                      Contains("fit.toml") && Contains("unit") && Contains("\"kN*m\""));
  }
  SECTION("the units row gives the unit, and must agree with the config") {
    Oscillogram record = Mill5Record(0.0, 0, 0.0, 1);
    record.units = {"kNm", "rpm"};
    ScratchDir dir;
    auto scene = Mill5Scene();
    WriteText(dir / "fit.toml", free + "[[channel]]\ncolumn = \"upper_spindle\"\n");
    CHECK(LoadFitConfig((dir / "fit.toml").string(), record, scene).channels[0].unit.name ==
          "kN*m");
    WriteText(dir / "fit.toml",
              free + "[[channel]]\ncolumn = \"upper_spindle\"\nunit = \"MN*m\"\n");
    CHECK_THROWS_WITH(
        LoadFitConfig((dir / "fit.toml").string(), record, scene),
        Contains("units row") && Contains("kN*m") && Contains("MN*m") && Contains("agree"));
    // A units row that is not a torque on a fitted channel.
    WriteText(dir / "fit.toml", free + "[[channel]]\ncolumn = \"lower_spindle\"\n");
    CHECK_THROWS_WITH(LoadFitConfig((dir / "fit.toml").string(), record, scene),
                      Contains("'rpm' is not a torque unit"));
    // ... unless the config says what the values are (a recorder's V after calibration).
    record.units = {"kNm", "V"};
    WriteText(dir / "fit.toml", free + "[[channel]]\ncolumn = \"lower_spindle\"\nunit = \"N*m\"\n");
    CHECK(LoadFitConfig((dir / "fit.toml").string(), record, scene).channels[0].unit.name == "N*m");
  }
}

TEST_CASE("a record in kN*m fits to the N*m record's values and reports in kN*m") {
  const Oscillogram record = Mill5Record(0.01, 12, 0.0, 3);
  Oscillogram in_kNm = record;
  for (auto& column : in_kNm.values) {
    for (double& v : column) v /= 1e3;
  }
  auto scene = Mill5Scene();
  const FitConfig config = Mill5Config(record, &scene);
  FitConfig kNm_config = config;
  for (auto& c : kNm_config.channels) c.unit = *ParseTorqueUnit("kN*m");
  const FitResult a = Fit(scene, record, config, FitOptions{});
  const FitResult b = Fit(scene, in_kNm, kNm_config, FitOptions{});
  // v / 1e3 * 1e3 is v to an ulp: the fits agree within their convergence tolerance.
  CheckSameFit(a, b, 1e-7);
  for (size_t c = 0; c < a.channels.size(); ++c) {
    CHECK(a.channels[c].unit == "N*m");
    CHECK(b.channels[c].unit == "kN*m");
    CHECK(b.channels[c].gain == Approx(a.channels[c].gain).epsilon(1e-7));
    CHECK(b.channels[c].offset == Approx(a.channels[c].offset / 1e3).epsilon(1e-6));
    CHECK(b.channels[c].rms_residual == Approx(a.channels[c].rms_residual / 1e3).epsilon(1e-6));
    CHECK(b.channels[c].measured[7] == in_kNm.values[c][7]);
  }
  // The plot draws each channel in its own unit.
  const std::string svg = FitPlotSvg(b, "kN*m record");
  CHECK_THAT(svg, Contains("torque, kN\u00b7m") && Contains("residual, kN\u00b7m"));
  CHECK_THAT(svg, !Contains("torque, N\u00b7m") && !Contains("torque, MN\u00b7m"));
}

TEST_CASE("The derivatives key takes sensitivity, forward or central") {
  CHECK_FALSE(Load(kFree).derivatives.has_value());
  for (const auto kind :
       {Derivatives::kSensitivity, Derivatives::kForward, Derivatives::kCentral}) {
    const auto config =
        Load(std::string("[fit]\nderivatives = \"") + DerivativesName(kind) + "\"\n" + kFree);
    REQUIRE(config.derivatives.has_value());
    CHECK(*config.derivatives == kind);
  }
  CHECK_THROWS_WITH(Load(std::string("[fit]\nderivatives = \"adjoint\"\n") + kFree),
                    Contains("fit.toml") && Contains("derivatives") && Contains("\"central\"") &&
                        Contains("adjoint"));
}
