// `millkit sweep` end to end: outputs, threads, exit codes, no partial files.
#include <algorithm>
#include <catch2/catch.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "support/run_cli.h"

using namespace millkit::testing;
using Catch::Matchers::Contains;
using Catch::Matchers::StartsWith;

namespace {

const std::string kConfig =
    "[sweep]\nmethod = \"grid\"\nlinks = [\"upper_spindle\", \"lower_spindle\"]\n"
    "[[parameter]]\nname = \"upper_spindle.damping\"\nlower = 1000\nupper = 9000\npoints = 3\n"
    "[[parameter]]\nname = \"lower_spindle.backlash\"\nvalues = [0.0, 0.03]\n";

std::string Mill5() { return "'" + SourcePath("datasets/scenes/mill5_bite.toml") + "'"; }

int Count(const std::string& text, const std::string& what) {
  int n = 0;
  for (auto at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

}  // namespace

TEST_CASE("sweep writes one row per case and a heat map of Kd per link for a two-parameter grid",
          "[sweep][cli]") {
  ScratchDir dir;
  WriteText(dir / "sweep.toml", kConfig);
  const auto run =
      RunMillkit("sweep " + Mill5() + " --config '" + (dir / "sweep.toml").string() + "' --out '" +
                 (dir / "cases.csv").string() + "' --plot '" + (dir / "kd.svg").string() + "'");
  REQUIRE(run.exit_code == 0);
  const std::string csv = ReadText(dir / "cases.csv");
  CHECK_THAT(csv, StartsWith("case,upper_spindle.damping,lower_spindle.backlash,status,events,"
                             "kd.upper_spindle,kd.lower_spindle,peak_Nm.upper_spindle,"
                             "peak_Nm.lower_spindle,message\n"));
  CHECK(std::count(csv.begin(), csv.end(), '\n') == 1 + 6);
  CHECK_THAT(csv, Contains("\n5,9000,0.03,ok,"));
  const std::string svg = ReadText(dir / "kd.svg");
  CHECK_THAT(svg,
             Contains(">Kd of upper_spindle</text>") && Contains(">Kd of lower_spindle</text>"));
  CHECK(Count(svg, "class=\"cell\"") == 2 * 6);  // 3 dampings × 2 backlashes per link
  CHECK(Count(svg, "class=\"colour-bar\"") == 2);
  CHECK_THAT(svg, Contains(">upper_spindle.damping (N*m*s/rad)</text>") &&
                      Contains(">lower_spindle.backlash (rad)</text>"));
  CHECK_THAT(svg, Contains(">5000</text>"));  // the middle damping level as a tick
  CHECK(Count(svg, "Kd vs") == 0);            // no marginal scatters
  CHECK_THAT(run.stderr_text, Contains("6 cases (0 failed)"));
}

TEST_CASE("sweep over one parameter draws a line of Kd per link against it", "[sweep][cli]") {
  ScratchDir dir;
  WriteText(dir / "sweep.toml",
            "[sweep]\nmethod = \"grid\"\nlinks = [\"upper_spindle\", \"lower_spindle\"]\n"
            "[[parameter]]\nname = \"upper_spindle.damping\"\nvalues = [9000, 1000, 5000]\n");
  const auto run =
      RunMillkit("sweep " + Mill5() + " --config '" + (dir / "sweep.toml").string() + "' --out '" +
                 (dir / "cases.csv").string() + "' --plot '" + (dir / "kd.svg").string() + "'");
  REQUIRE(run.exit_code == 0);
  const std::string svg = ReadText(dir / "kd.svg");
  CHECK_THAT(svg, Contains(">Kd vs upper_spindle.damping</text>"));
  CHECK(Count(svg, "class=\"cell\"") == 0);
  // Two links: two polylines of three points each, the second dashed.
  CHECK(Count(svg, "<polyline") == 2);
  CHECK(Count(svg, "stroke-dasharray=\"7 4\"") == 2);  // its polyline and legend line
  // The values were given as 9000, 1000, 5000: the line runs left to right, not back and forth.
  const auto begin = svg.find("points=\"", svg.find("<polyline")) + 8;
  std::istringstream points(svg.substr(begin, svg.find('"', begin) - begin));
  std::vector<double> x;
  for (std::string point; points >> point;) x.push_back(std::stod(point));
  CHECK(x.size() == 3);
  CHECK(std::is_sorted(x.begin(), x.end()));
}

TEST_CASE("sweep output is the same file for 1 and 2 threads", "[sweep][cli]") {
  ScratchDir dir;
  WriteText(dir / "sweep.toml", kConfig);
  const std::string common =
      "sweep " + Mill5() + " --config '" + (dir / "sweep.toml").string() + "'";
  REQUIRE(RunMillkit(common + " --out '" + (dir / "a.csv").string() + "' --threads 1").exit_code ==
          0);
  REQUIRE(RunMillkit(common + " --out '" + (dir / "b.csv").string() + "' --threads 2").exit_code ==
          0);
  CHECK(ReadText(dir / "a.csv") == ReadText(dir / "b.csv"));
}

TEST_CASE("sweep with a bad configuration exits 2 naming the key and writes nothing",
          "[sweep][cli][bad_input]") {
  ScratchDir dir;
  WriteText(dir / "sweep.toml",
            "[sweep]\nmethod = \"grid\"\n[[parameter]]\n"
            "name = \"upper_spindle.damping\"\nlower = 9\nupper = 1\n"
            "points = 3\n");
  const auto run =
      RunMillkit("sweep " + Mill5() + " --config '" + (dir / "sweep.toml").string() + "' --out '" +
                 (dir / "cases.csv").string() + "' --plot '" + (dir / "kd.svg").string() + "'");
  CHECK(run.exit_code == 2);
  CHECK_THAT(run.stderr_text,
             Contains("sweep.toml") && Contains("key 'upper'") && Contains("bounds reversed"));
  CHECK(dir.EntryCount() == 1);  // only sweep.toml
}

TEST_CASE("sweep refuses bad options with exit 2", "[sweep][cli][bad_input]") {
  ScratchDir dir;
  WriteText(dir / "sweep.toml", kConfig);
  const std::string base = "sweep " + Mill5() + " --config '" + (dir / "sweep.toml").string() + "'";
  auto run = RunMillkit(base + " --out '" + (dir / "c.csv").string() + "' --threads 0");
  CHECK(run.exit_code == 2);
  CHECK_THAT(run.stderr_text, Contains("--threads"));
  run = RunMillkit(base + " --out /no/such/dir/c.csv");
  CHECK(run.exit_code == 2);
  CHECK_THAT(run.stderr_text, Contains("does not exist"));
  run = RunMillkit(base + " --out '" + (dir / "c.csv").string() + "' --plot '" +
                   (dir / "c.csv").string() + "'");
  CHECK(run.exit_code == 2);
  CHECK_THAT(run.stderr_text, Contains("same file"));
  run = RunMillkit("sweep " + Mill5() + " --out '" + (dir / "c.csv").string() + "'");
  CHECK(run.exit_code == 2);  // --config missing
  CHECK(dir.EntryCount() == 1);
}

TEST_CASE("a sweep with a failed case writes every row and exits 3", "[sweep][cli]") {
  ScratchDir dir;
  // 1e12 N*m/rad puts the spindle's mode beyond what the scene's sampling resolves: that case
  // fails, its neighbour runs.
  WriteText(dir / "sweep.toml",
            "[sweep]\nmethod = \"grid\"\nlinks = [\"upper_spindle\"]\n[[parameter]]\n"
            "name = \"upper_spindle.stiffness\"\nvalues = [1.2e7, 1e12]\n");
  const auto run = RunMillkit("sweep " + Mill5() + " --config '" + (dir / "sweep.toml").string() +
                              "' --out '" + (dir / "cases.csv").string() + "'");
  INFO(run.stderr_text);
  CHECK(run.exit_code == 3);
  CHECK_THAT(run.stderr_text, Contains("1 case(s) failed"));
  const std::string csv = ReadText(dir / "cases.csv");
  CHECK(std::count(csv.begin(), csv.end(), '\n') == 1 + 2);
  CHECK_THAT(csv, Contains("\n0,1.2e+07,ok,") && Contains("\n1,1e+12,failed,"));
}
