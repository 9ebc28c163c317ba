// `millkit leveller …` end to end: outputs, exit codes, no partial output on bad input.
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <sstream>
#include <vector>

#include "millkit/io/csv.h"
#include "support/run_cli.h"

using Catch::Matchers::Contains;
using Catch::Matchers::WithinAbs;
using millkit::testing::ReadText;
using millkit::testing::RunMillkit;
using millkit::testing::ScratchDir;
using millkit::testing::SourcePath;
using millkit::testing::WriteText;

namespace {

constexpr double kSpecDigitsMm = 5e-5;
constexpr double kRoundTripMm = 1e-9;
constexpr int kExitBadInput = 2;

std::string Quote(const std::filesystem::path& p) { return "'" + p.string() + "'"; }

}  // namespace

TEST_CASE("leveller forward writes the SPEC's check values", "[leveller][cli]") {
  ScratchDir dir;
  WriteText(dir / "angles.csv", "beta1_deg,beta2_deg\n0,0\n90,90\n");
  const auto r = RunMillkit("leveller forward --in " + Quote(dir / "angles.csv") + " --out " +
                            Quote(dir / "y.csv"));
  REQUIRE(r.exit_code == 0);
  const auto table = millkit::ParseCsv(ReadText(dir / "y.csv"), "y.csv");
  REQUIRE(table.columns.size() == 5);
  CHECK_THAT(table.rows[0][table.Column("y1_mm")], WithinAbs(-0.2080, kSpecDigitsMm));
  CHECK_THAT(table.rows[1][table.Column("y3_mm")], WithinAbs(-15.0, kSpecDigitsMm));
}

TEST_CASE("leveller inverse round-trips the forward output through files", "[leveller][cli]") {
  ScratchDir dir;
  WriteText(dir / "angles.csv", "beta1_deg,beta2_deg\n12.5,-33\n-70,80\n");
  REQUIRE(RunMillkit("leveller forward --in " + Quote(dir / "angles.csv") + " --out " +
                     Quote(dir / "y.csv"))
              .exit_code == 0);
  const auto y = millkit::ParseCsv(ReadText(dir / "y.csv"), "y.csv");
  std::string targets = "y1_mm,y2_mm\n";
  for (const auto& row : y.rows) {
    char line[128];
    std::snprintf(line, sizeof(line), "%.15g,%.15g\n", row[2], row[3]);
    targets += line;
  }
  WriteText(dir / "targets.csv", targets);
  const auto r = RunMillkit("leveller inverse --in " + Quote(dir / "targets.csv") + " --out " +
                            Quote(dir / "b.csv") + " --encoder-deg 0.01 --geometry " +
                            Quote(SourcePath("datasets/leveller/leveller_default.toml")));
  INFO(r.stderr_text);
  REQUIRE(r.exit_code == 0);
  const auto b = millkit::ParseCsv(ReadText(dir / "b.csv"), "b.csv");
  CHECK_THAT(b.rows[0][b.Column("beta1_deg")], WithinAbs(12.5, 1e-7));
  CHECK_THAT(b.rows[1][b.Column("beta2_deg")], WithinAbs(80.0, 1e-7));
  CHECK(b.rows[0][b.Column("residual_mm")] <= kRoundTripMm);
  CHECK(b.rows[0][b.Column("accuracy_mm")] > 0.0);
}

TEST_CASE("leveller inverse writes every row with its status and exits 3 for an outside target",
          "[leveller][cli]") {
  ScratchDir dir;
  const bool hydraulic = GENERATE(false, true);
  INFO((hydraulic ? "cylinders" : "eccentrics"));
  const std::string variant = hydraulic ? " --hydraulic" : "";
  const std::string solved = hydraulic ? "ah_mm" : "beta1_deg";
  WriteText(dir / "targets.csv", "y1_mm,y2_mm\n0,0\n40,0\n1,-1\n");
  const auto r = RunMillkit("leveller inverse" + variant + " --in " + Quote(dir / "targets.csv") +
                            " --out " + Quote(dir / "b.csv"));
  CHECK(r.exit_code == 3);
  CHECK_THAT(r.stderr_text, Contains("targets.csv:3") && Contains("nearest reachable") &&
                                Contains("1 of 3 rows are not ok"));
  // Rows out of reach hold nan cells, which the (strict) reader refuses: split the lines here.
  const std::string text = ReadText(dir / "b.csv");
  std::vector<std::vector<std::string>> rows;
  std::istringstream lines(text);
  for (std::string line; std::getline(lines, line);) {
    std::vector<std::string> cells;
    std::istringstream in(line);
    for (std::string cell; std::getline(in, cell, ',');) cells.push_back(cell);
    rows.push_back(cells);
  }
  REQUIRE(rows.size() == 4);
  const auto& header = rows[0];
  const auto column = [&](const std::string& name) {
    return static_cast<size_t>(std::find(header.begin(), header.end(), name) - header.begin());
  };
  REQUIRE(column("status") == header.size() - 1);
  CHECK(rows[1].back() == "ok");
  CHECK(rows[2].back() == "unreachable");
  CHECK(rows[3].back() == "ok");
  CHECK(rows[2][column(solved)] == "nan");
  CHECK(std::stod(rows[1][column("nearest_y1_mm")]) == 0.0);  // a reachable target is its own
  const double n1 = std::stod(rows[2][column("nearest_y1_mm")]);
  const double n2 = std::stod(rows[2][column("nearest_y2_mm")]);
  REQUIRE(std::isfinite(n1));
  REQUIRE(std::isfinite(n2));
  SECTION("the nearest reachable pair, typed back as a target, is accepted") {
    char line[128];
    std::snprintf(line, sizeof(line), "y1_mm,y2_mm\n%.6f,%.6f\n", n1, n2);
    WriteText(dir / "again.csv", line);
    const auto again = RunMillkit("leveller inverse" + variant + " --in " +
                                  Quote(dir / "again.csv") + " --out " + Quote(dir / "c.csv"));
    INFO(again.stderr_text);
    CHECK(again.exit_code == 0);
    CHECK_THAT(ReadText(dir / "c.csv"), Contains(",ok\n"));
  }
}

TEST_CASE("leveller forces reproduces the seed's table in JSON when Mw is given",
          "[leveller][cli]") {
  ScratchDir dir;
  const auto r = RunMillkit(
      "leveller forces --yield-mpa 550 --width-mm 1900 --thickness-mm 6 --mw-nm 3460 --out " +
      Quote(dir / "f.json"));
  REQUIRE(r.exit_code == 0);
  const auto json = nlohmann::json::parse(ReadText(dir / "f.json"));
  CHECK_THAT(json["forces_kN"][2].get<double>(), WithinAbs(376.2, 5e-4));  // seed 004 §1
  CHECK_THAT(json["forces_kN"][6].get<double>(), WithinAbs(34.6, 5e-4));
  CHECK(json["mw_given"].get<bool>());
}

TEST_CASE(
    "leveller table writes every strip's row with status and warnings, exit 3 when one is "
    "out of reach",
    "[leveller][cli]") {
  ScratchDir dir;
  const auto r =
      RunMillkit("leveller table --strips " + Quote(SourcePath("datasets/leveller/strips.csv")) +
                 " --out " + Quote(dir / "t.csv"));
  INFO(r.stderr_text);
  // 70 % of 1.6 mm (line 4) needs more plunge than the linkage has.
  CHECK(r.exit_code == 3);
  CHECK_THAT(r.stderr_text, Contains("rows are not ok (status column"));
  const std::string text = ReadText(dir / "t.csv");
  CHECK_THAT(text, Contains("accuracy_mm,status,warnings\n") && Contains("beta1_deg") &&
                       Contains("power_kW"));
  CHECK_THAT(text, Contains("\n4,") && Contains(",unreachable,stroke:"));
  CHECK_THAT(text, Contains("exceeds motor_power_kW"));
  SECTION("a strip list within reach exits 0, its limit warnings kept") {
    WriteText(dir / "ok.csv",
              "yield_mpa,youngs_mpa,thickness_mm,width_mm,entry_plastic_ratio\n"
              "550,210000,3,1250,0.6\n");
    const auto ok = RunMillkit("leveller table --strips " + Quote(dir / "ok.csv") + " --out " +
                               Quote(dir / "ok_table.csv"));
    INFO(ok.stderr_text);
    CHECK(ok.exit_code == 0);
    CHECK_THAT(ReadText(dir / "ok_table.csv"), Contains(",ok,"));
  }
}

TEST_CASE("Bad leveller input exits 2 with the file, line or key named and no output",
          "[leveller][cli]") {
  struct Case {
    std::string name;
    std::string file;
    std::string content;
    std::string args;  // {in} and {out} replaced
    std::string expect;
  };
  const Case cases[] = {
      {"malformed CSV", "angles.csv", "beta1_deg,beta2_deg\n0,abc\n",
       "leveller forward --in {in} --out {out}", "angles.csv"},
      {"missing column", "targets.csv", "y1_mm,y3_mm\n0,0\n",
       "leveller inverse --in {in} --out {out}", "y2_mm"},
      {"angle outside working range", "angles.csv", "beta1_deg,beta2_deg\n0,0\n95,0\n",
       "leveller forward --in {in} --out {out}", "angles.csv:3"},
      {"negative thickness in the strip list", "strips.csv",
       "yield_mpa,thickness_mm,width_mm,entry_plastic_ratio\n550,-3,1000,0.5\n",
       "leveller table --strips {in} --out {out}", "thickness_mm' must be > 0"},
      {"zero yield in the strip list", "strips.csv",
       "yield_mpa,thickness_mm,width_mm,entry_plastic_ratio\n0,3,1000,0.5\n",
       "leveller table --strips {in} --out {out}", "yield_mpa' must be > 0"},
      {"malformed TOML", "g.toml", "[linkage\nhk_mm = 1\n",
       "leveller forward --in " + Quote(SourcePath("datasets/leveller/angles.csv")) +
           " --geometry {in} --out {out}",
       "TOML syntax"},
      {"unknown TOML key", "g.toml", "[machine]\nefficency = 0.8\n",
       "leveller table --strips " + Quote(SourcePath("datasets/leveller/strips.csv")) +
           " --geometry {in} --out {out}",
       "key 'efficency'"},
      {"degenerate geometry", "g.toml", "[linkage]\ngj_mm = 100\n",
       "leveller forward --in " + Quote(SourcePath("datasets/leveller/angles.csv")) +
           " --geometry {in} --out {out}",
       "rods cannot close"},
  };
  for (const auto& c : cases) {
    SECTION(c.name) {
      ScratchDir dir;
      WriteText(dir / c.file, c.content);
      std::string args = c.args;
      args.replace(args.find("{in}"), 4, Quote(dir / c.file));
      args.replace(args.find("{out}"), 5, Quote(dir / "out.csv"));
      const auto r = RunMillkit(args);
      INFO(r.stderr_text);
      CHECK(r.exit_code == kExitBadInput);
      CHECK_THAT(r.stderr_text, Contains(c.expect));
      CHECK(dir.EntryCount() == 1);  // only the input: no partial output
    }
  }
}

TEST_CASE("leveller forces rejects a negative thickness and a zero yield", "[leveller][cli]") {
  ScratchDir dir;
  auto r = RunMillkit("leveller forces --yield-mpa 550 --width-mm 1900 --thickness-mm -6 --out " +
                      Quote(dir / "f.json"));
  CHECK(r.exit_code == kExitBadInput);
  CHECK_THAT(r.stderr_text, Contains("--thickness-mm must be > 0"));
  r = RunMillkit("leveller forces --yield-mpa 0 --width-mm 1900 --thickness-mm 6 --out " +
                 Quote(dir / "f.json"));
  CHECK(r.exit_code == kExitBadInput);
  CHECK_THAT(r.stderr_text, Contains("--yield-mpa must be > 0"));
  CHECK(dir.EntryCount() == 0);
}

TEST_CASE("Every leveller subcommand has --help", "[leveller][cli]") {
  for (const char* sub : {"forward", "inverse", "forces", "table"}) {
    const auto r = RunMillkit(std::string("leveller ") + sub + " --help");
    INFO(sub);
    CHECK(r.exit_code == 0);
    CHECK_THAT(r.stdout_text, Contains("--out"));
  }
}
