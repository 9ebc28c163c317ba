// The coupling configuration: what it accepts and every rule it enforces with file and key named.
#include "millkit/optimize/coupling/coupling_config.h"

#include <catch2/catch.hpp>
#include <cmath>

#include "millkit/io/input_error.h"
#include "support/study_support.h"

using namespace millkit::coupling;
using Catch::Matchers::Contains;
using millkit::testing::ScratchDir;
using millkit::testing::WriteText;

namespace {

using millkit::testing::Mill5Scene;

CouplingStudy Load(const std::string& text) {
  ScratchDir dir;
  WriteText(dir / "coupling.toml", text);
  return LoadCouplingStudy((dir / "coupling.toml").string(), Mill5Scene());
}

std::string ErrorOf(const std::string& text) {
  const std::string message = millkit::testing::InputErrorOfFile(
      "coupling.toml", text,
      [](const std::string& path) { LoadCouplingStudy(path, Mill5Scene()); });
  INFO(text);
  CHECK_FALSE(message.empty());
  return message;
}

const std::string kVariable =
    "[[variable]]\nname = \"upper_spindle.stiffness\"\nlower = 2e6\nupper = 5e7\n";

}  // namespace

TEST_CASE("a coupling configuration with every table loads", "[coupling][config]") {
  const CouplingStudy study =
      Load("[objective]\nlinks = [\"upper_spindle\", \"lower_spindle\"]\n" + kVariable +
           "[[variable]]\nname = \"upper_spindle.damping\"\nlower = 0\nupper = 2e4\n"
           "[[twist_limit]]\nlink = \"upper_spindle\"\nmax_twist = 0.05\n"
           "[[twist_limit]]\nlink = \"lower_spindle\"\nmax_twist = 0.06\nrated_torque = -2e5\n"
           "[frequency_limit]\nmin_frequency = 5\n"
           "[optimizer]\nglobal_evaluations = 50\nlocal = \"cobyla\"\nlocal_evaluations = 20\n"
           "xtol = 1e-4\n[curve]\npoints = 11\nwidth = 0.25\n");
  const CouplingProblem& p = study.problem;
  REQUIRE(p.variables.size() == 2);
  CHECK(p.variables[0].scale == millkit::sweep::Scale::kLog);     // stiffness default
  CHECK(p.variables[1].scale == millkit::sweep::Scale::kLinear);  // damping default
  CHECK(p.counted_links.size() == 2);
  REQUIRE(p.twist_limits.size() == 2);
  // Default rated torque: |m_s| of the link under the final loads.
  const auto static_torque = millkit::driveline::StaticLinkTorques(Mill5Scene());
  CHECK(p.twist_limits[0].rated_torque_Nm == std::abs(static_torque[p.twist_limits[0].link]));
  CHECK(p.twist_limits[1].rated_torque_Nm == 2e5);
  CHECK(p.min_frequency_Hz == 5.0);
  CHECK(study.options.local_algorithm == millkit::optimize::Algorithm::kLnCobyla);
  CHECK(study.options.global_evaluations == 50);
  CHECK(study.curve.points == 11);
}

TEST_CASE("coupling configuration errors name the file, the key and the rule",
          "[coupling][config][bad_input]") {
  CHECK_THAT(ErrorOf(kVariable + "[extra]\n"),
             Contains("coupling.toml") && Contains("key 'extra'"));
  CHECK_THAT(ErrorOf("[objective]\n"), Contains("key 'variable'") && Contains("required"));
  CHECK_THAT(ErrorOf("[[variable]]\nname = \"motor.inertia\"\nlower = 1\nupper = 2\n"),
             Contains("key 'name'") && Contains("only <link>.stiffness and <link>.damping"));
  CHECK_THAT(ErrorOf("[[variable]]\nname = \"spindle.stiffness\"\nlower = 1\nupper = 2\n"),
             Contains("key 'name'") && Contains("no link named 'spindle'"));
  CHECK_THAT(
      ErrorOf("[[variable]]\nname = \"upper_spindle.stiffness\"\nlower = 5e7\nupper = 2e6\n"),
      Contains("key 'upper'") && Contains("bounds reversed"));
  CHECK_THAT(
      ErrorOf("[[variable]]\nname = \"upper_spindle.stiffness\"\nlower = 5e7\nupper = 5e7\n"),
      Contains("empty range"));
  CHECK_THAT(ErrorOf("[[variable]]\nname = \"upper_spindle.stiffness\"\nlower = 0\nupper = 5e7\n"),
             Contains("key 'lower'") && Contains("> 0"));
  CHECK_THAT(ErrorOf(kVariable + kVariable), Contains("given twice"));
  CHECK_THAT(ErrorOf(kVariable + "[objective]\nlinks = [\"nope\"]\n"),
             Contains("key 'links'") && Contains("no link named 'nope'"));
  CHECK_THAT(ErrorOf(kVariable + "[[twist_limit]]\nlink = \"upper_spindle\"\nmax_twist = -1\n"),
             Contains("key 'max_twist'") && Contains("> 0"));
  CHECK_THAT(ErrorOf(kVariable + "[[twist_limit]]\nlink = \"upper_spindle\"\nmax_twist = 0.1\n"
                                 "[[twist_limit]]\nlink = \"upper_spindle\"\nmax_twist = 0.2\n"),
             Contains("second limit"));
  CHECK_THAT(ErrorOf(kVariable + "[frequency_limit]\nmin_frequency = 0\n"),
             Contains("key 'min_frequency'"));
  CHECK_THAT(ErrorOf(kVariable + "[optimizer]\nlocal = \"nelder-mead\"\n"),
             Contains("key 'local'"));
  CHECK_THAT(ErrorOf(kVariable + "[optimizer]\nlocal = \"none\"\nlocal_evaluations = 3\n"),
             Contains("key 'local_evaluations'"));
  CHECK_THAT(ErrorOf(kVariable + "[optimizer]\nglobal_evaluations = 2.5\n"),
             Contains("key 'global_evaluations'") && Contains("integer"));
  CHECK_THAT(ErrorOf(kVariable + "[curve]\nwidth = 0\n"), Contains("key 'width'"));
}
