// What `leveller forces` writes (forces_report.h) and the strip rule it checks (FindStripDefects).
#include "millkit/leveller/forces_report.h"

#include <catch2/catch.hpp>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>

#include "millkit/io/input_error.h"

using namespace millkit::leveller;
using Catch::Matchers::Contains;

TEST_CASE("The forces JSON carries the strip, the machine and the report's values exactly",
          "[leveller][forces]") {
  const Strip strip{550.0, 2.1e5, 6.0, 1900.0};
  MachineData machine;
  machine.efficiency = 0.8;
  ForcesOptions options;
  options.mw_override_Nm = 3460.0;
  const ForcesReport report = ComputeForces(strip, machine, options);
  const std::string text = ForcesReportJson(strip, machine, report);
  REQUIRE(text.back() == '\n');
  const auto json = nlohmann::json::parse(text);
  CHECK(json["strip"]["thickness_mm"].get<double>() == 6.0);
  CHECK(json["mw_given"].get<bool>());
  CHECK(json["mw_Nm"].get<double>() == 3460.0);
  CHECK(json["ms_Nm"].get<double>() == report.ms_Nm);
  REQUIRE(json["forces_kN"].size() == 7);
  for (int i = 0; i < 7; ++i) {
    CHECK(json["forces_kN"][i].get<double>() == report.forces_kN[i]);
    CHECK(json["moments_Nm"][i].get<double>() == report.moments_Nm[i]);
  }
  CHECK(json["power_kW"].get<double>() == report.power_kW);
  CHECK(json["machine"]["efficiency"].get<double>() == 0.8);
  CHECK(json["warnings"].size() == report.warnings.size());
}

TEST_CASE("The forces summary prints P1..P7 and the power to their decimals",
          "[leveller][forces]") {
  const Strip strip{550.0, 2.1e5, 6.0, 1900.0};
  const ForcesReport stated = ComputeForces(strip, MachineData{}, ForcesOptions{});
  const std::string text = FormatForcesSummary(stated);
  CHECK(text.rfind("Mw = 6270.0 N*m, Ms = 9405.0 N*m", 0) == 0);
  for (int i = 0; i < 7; ++i) {
    char line[64];
    std::snprintf(line, sizeof(line), "\nP%d = %.3f kN\n", i + 1, stated.forces_kN[i]);
    CHECK_THAT(text, Contains(line));
  }
  char power[32];
  std::snprintf(power, sizeof(power), "N = %.2f kW\n", stated.power_kW);
  CHECK_THAT(text, Contains(power));
  ForcesOptions given;
  given.mw_override_Nm = 3460.0;
  const std::string seed = FormatForcesSummary(ComputeForces(strip, MachineData{}, given));
  CHECK(seed.rfind("Mw = 3460.0 N*m (given),", 0) == 0);
  CHECK_THAT(seed, Contains("\nP3 = 376.200 kN\n"));
}

TEST_CASE("FindStripDefects names every field that is not > 0, and ValidateStrip the first",
          "[leveller][forces]") {
  CHECK(FindStripDefects(Strip{}).empty());
  const Strip bad{550.0, -1.0, 6.0, 0.0};
  const auto defects = FindStripDefects(bad);
  REQUIRE(defects.size() == 2);
  CHECK(defects[0].field == "youngs_mpa");
  CHECK(defects[0].rule == "must be > 0 (got -1)");
  CHECK(defects[1].field == "width_mm");
  CHECK(defects[1].rule == "must be > 0 (got 0)");
  CHECK_THROWS_WITH(ValidateStrip(bad, "strip"), "strip: youngs_mpa must be > 0 (got -1)");
  CHECK(FindStripDefects(Strip{550.0, 2.1e5, std::nan(""), 1900.0}).at(0).field == "thickness_mm");
}
