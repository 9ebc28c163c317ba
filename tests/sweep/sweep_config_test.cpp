// The sweep configuration: what it accepts, and every rule it enforces with file and key named.
#include "millkit/sweep/sweep_config.h"

#include <catch2/catch.hpp>

#include "millkit/io/input_error.h"
#include "support/study_support.h"

using namespace millkit::sweep;
using Catch::Matchers::Contains;
using millkit::testing::ScratchDir;
using millkit::testing::WriteText;

namespace {

using millkit::testing::Mill5Scene;

SweepConfig Load(const ScratchDir& dir, const std::string& text) {
  const auto path = dir / "sweep.toml";
  WriteText(path, text);
  return LoadSweepConfig(path.string(), Mill5Scene());
}

std::string ErrorOf(const std::string& text) {
  const std::string message = millkit::testing::InputErrorOfFile(
      "sweep.toml", text, [](const std::string& path) { LoadSweepConfig(path, Mill5Scene()); });
  INFO(text);
  CHECK_FALSE(message.empty());
  return message;
}

const std::string kGridHead = "[sweep]\nmethod = \"grid\"\n";
const std::string kLhsHead = "[sweep]\nmethod = \"lhs\"\nsamples = 10\n";

}  // namespace

TEST_CASE("a grid configuration gives the product of its parameters' points", "[sweep][config]") {
  ScratchDir dir;
  const SweepConfig config =
      Load(dir, kGridHead +
                    "links = [\"lower_spindle\"]\n"
                    "[[parameter]]\nname = \"upper_spindle.damping\"\nlower = 1000\n"
                    "upper = 3000\npoints = 3\n"
                    "[[parameter]]\nname = \"bite_time\"\nvalues = [0.04, 0.05]\n");
  CHECK(config.method == SweepConfig::Method::kGrid);
  CHECK(config.links == std::vector<int>{Mill5Scene().LinkIndex("lower_spindle")});
  const CaseList cases = config.Cases();
  REQUIRE(cases.size() == 6);
  CHECK(cases[5] == std::vector<double>{3000.0, 0.05});
}

TEST_CASE("an lhs configuration gives `samples` cases from its seed", "[sweep][config]") {
  ScratchDir dir;
  const SweepConfig config = Load(dir, kLhsHead +
                                           "seed = 3\n[[parameter]]\nname = \"lower_roll.load\"\n"
                                           "lower = -150000\nupper = -100000\n");
  CHECK(config.seed == 3);
  CHECK(config.Cases().size() == 10);
  CHECK(config.links.size() == Mill5Scene().links.size());  // default: every link
}

TEST_CASE("sweep configuration errors name the file, the key and the rule",
          "[sweep][config][bad_input]") {
  const std::string param = "[[parameter]]\nname = \"upper_spindle.damping\"\n";
  SECTION("unknown key") {
    const auto message =
        ErrorOf(kGridHead + "colour = 1\n" + param + "lower = 1\nupper = 2\npoints = 2\n");
    CHECK_THAT(message,
               Contains("sweep.toml") && Contains("key 'colour'") && Contains("unknown key"));
  }
  SECTION("unknown parameter name") {
    const auto message = ErrorOf(kGridHead +
                                 "[[parameter]]\nname = \"upper_spindel.damping\"\n"
                                 "lower = 1\nupper = 2\npoints = 2\n");
    CHECK_THAT(message, Contains("sweep.toml") && Contains("key 'name'") &&
                            Contains("no link named 'upper_spindel'"));
  }
  SECTION("unknown property") {
    CHECK_THAT(ErrorOf(kGridHead + "[[parameter]]\nname = \"upper_spindle.colour\"\n"
                                   "lower = 1\nupper = 2\npoints = 2\n"),
               Contains("unknown parameter 'upper_spindle.colour'"));
  }
  SECTION("empty range") {
    CHECK_THAT(ErrorOf(kGridHead + param + "lower = 5\nupper = 5\npoints = 3\n"),
               Contains("key 'upper'") && Contains("empty range"));
  }
  SECTION("bounds reversed") {
    CHECK_THAT(ErrorOf(kLhsHead + param + "lower = 5\nupper = 1\n"),
               Contains("key 'upper'") && Contains("bounds reversed"));
  }
  SECTION("outside the physical range") {
    CHECK_THAT(ErrorOf(kLhsHead + param + "lower = -5\nupper = 1\n"),
               Contains("key 'lower'") && Contains(">= 0"));
    CHECK_THAT(ErrorOf(kGridHead + "[[parameter]]\nname = \"upper_spindle.gap_position\"\n"
                                   "values = [0.5, 1.5]\n"),
               Contains("key 'values'") && Contains("[-1, 1]"));
  }
  SECTION("a bite after the end of the run") {
    CHECK_THAT(ErrorOf(kGridHead + "[[parameter]]\nname = \"bite_time\"\nvalues = [0.1, 0.5]\n"),
               Contains("key 'values'") && Contains("[0, duration = 0.5)"));
  }
  SECTION("log scale from zero") {
    CHECK_THAT(ErrorOf(kLhsHead + param + "lower = 0\nupper = 1\nscale = \"log\"\n"),
               Contains("log scale needs lower > 0"));
  }
  SECTION("grid without points, or lhs with points") {
    CHECK_THAT(ErrorOf(kGridHead + param + "lower = 1\nupper = 2\n"),
               Contains("key 'points'") && Contains("required"));
    CHECK_THAT(ErrorOf(kLhsHead + param + "lower = 1\nupper = 2\npoints = 4\n"),
               Contains("key 'points'") && Contains("unknown key"));
    CHECK_THAT(ErrorOf(kGridHead + param + "lower = 1\nupper = 2\npoints = 1\n"),
               Contains("key 'points'"));
  }
  SECTION("lhs without samples") {
    CHECK_THAT(ErrorOf("[sweep]\nmethod = \"lhs\"\n" + param + "lower = 1\nupper = 2\n"),
               Contains("key 'samples'") && Contains("required"));
  }
  SECTION("a parameter swept twice") {
    const std::string p = param + "lower = 1\nupper = 2\npoints = 2\n";
    CHECK_THAT(ErrorOf(kGridHead + p + p), Contains("swept twice"));
  }
  SECTION("an unknown link to report") {
    CHECK_THAT(ErrorOf(kGridHead + "links = [\"spindle\"]\n" + param +
                       "lower = 1\nupper = 2\npoints = 2\n"),
               Contains("key 'links'") && Contains("no link named 'spindle'"));
  }
  SECTION("no parameter, no method") {
    CHECK_THAT(ErrorOf(kGridHead), Contains("[[parameter]]"));
    CHECK_THAT(ErrorOf("[sweep]\nmethod = \"random\"\n"), Contains("key 'method'"));
  }
  SECTION("a grid too large to run") {
    const std::string big = "lower = 1\nupper = 2\npoints = 1001\n";
    CHECK_THAT(ErrorOf(kGridHead + param + big +
                       "[[parameter]]\nname = \"lower_spindle.damping\"\n" + big),
               Contains("1002001 cases"));
  }
}
