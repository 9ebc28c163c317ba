// `millkit coupling` end to end on the five-mass scene: outputs, constraints, exit codes.
#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include "support/run_cli.h"

using namespace millkit::testing;
using Catch::Matchers::Contains;
using Catch::Matchers::StartsWith;

namespace {

const std::string kConfig =
    "[objective]\nlinks = [\"upper_spindle\", \"lower_spindle\"]\n"
    "[[variable]]\nname = \"upper_spindle.stiffness\"\nlower = 2e6\nupper = 5e7\n"
    "[[variable]]\nname = \"lower_spindle.stiffness\"\nlower = 2e6\nupper = 5e7\n"
    "[[twist_limit]]\nlink = \"upper_spindle\"\nmax_twist = 0.05\n"
    "[[twist_limit]]\nlink = \"lower_spindle\"\nmax_twist = 0.05\n"
    "[frequency_limit]\nmin_frequency = 8\n"
    "[optimizer]\nglobal_evaluations = 60\nlocal_evaluations = 30\n[curve]\npoints = 9\n";

std::string Mill5() { return "'" + SourcePath("datasets/scenes/mill5_bite.toml") + "'"; }

}  // namespace

TEST_CASE("coupling writes the answer, the curve and the plot, and the answer meets every limit",
          "[coupling][cli]") {
  ScratchDir dir;
  WriteText(dir / "c.toml", kConfig);
  const auto run =
      RunMillkit("coupling " + Mill5() + " --config '" + (dir / "c.toml").string() + "' --out '" +
                 (dir / "r.json").string() + "' --curve '" + (dir / "curve.csv").string() +
                 "' --plot '" + (dir / "curve.svg").string() + "' --threads 2");
  INFO(run.stderr_text);
  REQUIRE(run.exit_code == 0);
  const auto json = nlohmann::json::parse(ReadText(dir / "r.json"));
  REQUIRE(json["found"] == true);
  const auto& best = json["best"];
  CHECK(best["constraints_met"] == true);
  CHECK(best["lowest_frequency_Hz"].get<double>() >= 8.0);
  for (const auto& twist : best["twist"]) {
    CHECK(twist["twist_rad"].get<double>() <= twist["max_twist_rad"].get<double>());
  }
  for (const auto& v : json["variables"]) {
    const double value = best["values"][v["name"].get<std::string>()].get<double>();
    CHECK(value >= v["effective_lower"].get<double>());
    CHECK(value <= v["effective_upper"].get<double>());
  }
  // The scene as given lies inside the bounds: the answer is never worse.
  REQUIRE(json.contains("scene_as_given"));
  CHECK(best["kd_max"].get<double>() <= json["scene_as_given"]["kd_max"].get<double>());
  CHECK(json["summary"]["simulations"].get<int>() > 0);
  CHECK_THAT(ReadText(dir / "curve.csv"),
             StartsWith("variable,value,status,feasible,lowest_frequency_Hz,"
                        "twist_rad.upper_spindle,twist_rad.lower_spindle,kd_max,"
                        "kd.upper_spindle,kd.lower_spindle,message\n"));
  const std::string svg = ReadText(dir / "curve.svg");
  CHECK_THAT(svg, Contains("Kd vs upper_spindle.stiffness"));
  // Two counted links: Kd max is a wide light band under them (it runs along the larger one),
  // the second link's line is dashed, so neither curve hides another.
  CHECK_THAT(svg, Contains("stroke-width=\"7.00\" stroke-opacity=\"0.30\""));
  CHECK_THAT(svg, Contains("stroke-dasharray=\"7 4\""));
  CHECK_THAT(run.stdout_text, Contains("optimum") && Contains("scene as given"));
}

TEST_CASE("coupling with an impossible limit exits 2 and writes nothing",
          "[coupling][cli][bad_input]") {
  ScratchDir dir;
  std::string config = kConfig;
  config.replace(config.find("min_frequency = 8"), 17, "min_frequency = 80");
  WriteText(dir / "c.toml", config);
  const auto run =
      RunMillkit("coupling " + Mill5() + " --config '" + (dir / "c.toml").string() + "' --out '" +
                 (dir / "r.json").string() + "' --curve '" + (dir / "curve.csv").string() + "'");
  CHECK(run.exit_code == 2);
  CHECK_THAT(run.stderr_text,
             Contains("c.toml") && Contains("min_frequency") && Contains("cannot be met"));
  CHECK(dir.EntryCount() == 1);
}

TEST_CASE("coupling with an unknown key exits 2 naming it", "[coupling][cli][bad_input]") {
  ScratchDir dir;
  WriteText(dir / "c.toml", kConfig + "[curve2]\n");
  const auto run = RunMillkit("coupling " + Mill5() + " --config '" + (dir / "c.toml").string() +
                              "' --out '" + (dir / "r.json").string() + "'");
  CHECK(run.exit_code == 2);
  CHECK_THAT(run.stderr_text, Contains("key 'curve2'"));
  CHECK(dir.EntryCount() == 1);
}

TEST_CASE("coupling that finds no feasible point exits 1 and writes nothing", "[coupling][cli]") {
  // 21.9 Hz is just below the lowest frequency at the stiffest bounds (21.96 Hz), so the limit
  // can be met, but one DIRECT step from the centre of the box meets only infeasible points and
  // the scene as given (f1 = 15.5 Hz) breaks the limit too.
  ScratchDir dir;
  std::string config = kConfig;
  config.replace(config.find("min_frequency = 8"), 17, "min_frequency = 21.9");
  config.replace(config.find("global_evaluations = 60\nlocal_evaluations = 30"), 46,
                 "global_evaluations = 1\nlocal = \"none\"");
  WriteText(dir / "c.toml", config);
  const auto run = RunMillkit("coupling " + Mill5() + " --config '" + (dir / "c.toml").string() +
                              "' --out '" + (dir / "r.json").string() + "'");
  CHECK(run.exit_code == 1);
  CHECK_THAT(run.stderr_text, Contains("no feasible point"));
  CHECK(dir.EntryCount() == 1);
}
