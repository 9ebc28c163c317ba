// Fit configs: every rule of identify/fit_config.h names the file and key.
#include "identify/fit_config.h"

#include <catch2/catch.hpp>

#include "identify/fit_fixture.h"
#include "io/input_error.h"
#include "support/run_cli.h"

using namespace millkit::identify;
using namespace millkit::identify::testing;
using millkit::InputError;
using millkit::testing::ScratchDir;
using millkit::testing::WriteText;
using Catch::Matchers::Contains;

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
  CHECK_THROWS_WITH(Load("[[free]]\nname = \"upper_spindle.colour\"\nlower = 0\nupper = 1\n"),
                    Contains("fit.toml") && Contains("upper_spindle.colour") &&
                        Contains("key 'name'"));
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
  CHECK_THROWS_WITH(Load(std::string("[fit]\nwindows = [0, 1]\n") + kFree), Contains("unknown key"));
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
