// The inverse table (optimize/leveller/inverse_table.h): the NLopt and closed-form methods on
// targets from the forward map, a target out of reach with its nearest reachable pair, and the
// hydraulic drive; each written through FormatInverseTable and read back.
#include "millkit/optimize/leveller/inverse_table.h"

#include <catch2/catch.hpp>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "millkit/io/input_error.h"

using namespace millkit::leveller;
using Catch::Matchers::Contains;
using Catch::Matchers::WithinAbs;

namespace {

constexpr double kAngleDeg = 1e-6;
constexpr double kRoundTripMm = 1e-9;
// 15 significant digits of values below 100 mm.
constexpr double kCellDigitsMm = 1e-12;

// The cells of each data line of the written CSV (it has text and nan cells, which ParseCsv
// refuses).
std::vector<std::vector<std::string>> Cells(const std::string& csv) {
  std::vector<std::vector<std::string>> rows;
  std::istringstream lines(csv);
  std::string line;
  std::getline(lines, line);  // header
  while (std::getline(lines, line)) {
    std::vector<std::string> cells;
    std::istringstream split(line);
    std::string cell;
    while (std::getline(split, cell, ',')) cells.push_back(cell);
    rows.push_back(cells);
  }
  return rows;
}

millkit::CsvTable TargetsFor(const Linkage& linkage,
                             const std::vector<std::pair<double, double>>& angles,
                             const std::string& extra_row) {
  std::string text = "y1_mm,y2_mm\n";
  for (const auto& [b1, b2] : angles) {
    Intermesh<double> y{};
    REQUIRE(linkage.Forward(b1, b2, &y));
    char line[96];
    std::snprintf(line, sizeof(line), "%.17g,%.17g\n", y.y1, y.y2);
    text += line;
  }
  return millkit::ParseCsv(text + extra_row, "targets.csv");
}

}  // namespace

TEST_CASE("The inverse table returns the angles of the forward map by NLopt and closed form",
          "[leveller][inverse_table]") {
  const LevellerConfig config = DefaultLevellerConfig();
  const Linkage linkage(config.linkage);
  const std::vector<std::pair<double, double>> angles{{12.5, -33.0}, {-70.0, 80.0}};
  const auto targets = TargetsFor(linkage, angles, "40,0\n");
  for (const auto method : {InverseMethod::kNlopt, InverseMethod::kClosedForm}) {
    InverseTableOptions options;
    options.method = method;
    const InverseTable table = ComputeInverseTable(targets, config, options);
    REQUIRE(table.rows.size() == 3);
    CHECK(table.NotOkCount() == 1);
    const auto cells = Cells(FormatInverseTable(table));
    REQUIRE(cells.size() == 3);
    for (std::size_t r = 0; r < angles.size(); ++r) {
      REQUIRE(cells[r].size() == 10);
      CHECK(cells[r][9] == "ok");
      CHECK_THAT(std::stod(cells[r][2]), WithinAbs(angles[r].first, kAngleDeg));
      CHECK_THAT(std::stod(cells[r][3]), WithinAbs(angles[r].second, kAngleDeg));
      CHECK(std::stod(cells[r][5]) <= kRoundTripMm);  // residual_mm
      CHECK(std::stod(cells[r][6]) > 0.0);            // accuracy_mm
      // A reachable target is its own nearest reachable pair (15 digits in the file).
      CHECK(table.rows[r].nearest_y1_mm == targets.rows[r][0]);
      CHECK_THAT(std::stod(cells[r][8]), WithinAbs(targets.rows[r][1], kCellDigitsMm));
    }
    // Out of reach: no angles, the nearest reachable pair, a warning naming it.
    CHECK(cells[2][2] == "nan");
    CHECK(cells[2][9] == "unreachable");
    const double n1 = std::stod(cells[2][7]);
    const double n2 = std::stod(cells[2][8]);
    CHECK(n1 < 40.0);
    CHECK(linkage.InverseClosedForm(n1, n2).status != InverseStatus::kBeamTiltImpossible);
    REQUIRE(table.rows[2].warnings.size() == 1);
    CHECK_THAT(table.rows[2].warnings[0],
               Contains("unreachable: target (40, 0) is outside the linkage's reach") &&
                   Contains("nearest reachable (y1_mm, y2_mm)"));
  }
}

TEST_CASE("The inverse table gives cylinder lengths for the hydraulic drive",
          "[leveller][inverse_table]") {
  const LevellerConfig config = DefaultLevellerConfig();
  const Linkage linkage(config.linkage);
  Intermesh<double> y{};
  REQUIRE(linkage.ForwardLengths(530.0, 550.0, &y));
  char text[128];
  std::snprintf(text, sizeof(text), "y1_mm,y2_mm\n%.17g,%.17g\n", y.y1, y.y2);
  InverseTableOptions options;
  options.drive = LinkageDrive::kHydraulic;
  const InverseTable table =
      ComputeInverseTable(millkit::ParseCsv(text, "targets.csv"), config, options);
  const auto cells = Cells(FormatInverseTable(table));
  REQUIRE(cells.size() == 1);
  REQUIRE(cells[0].size() == 9);
  CHECK_THAT(std::stod(cells[0][2]), WithinAbs(530.0, 1e-6));
  CHECK_THAT(std::stod(cells[0][3]), WithinAbs(550.0, 1e-6));
  CHECK(cells[0][8] == "ok");
}

TEST_CASE("The inverse table refuses a bad encoder resolution, an output column and no target",
          "[leveller][inverse_table]") {
  const LevellerConfig config = DefaultLevellerConfig();
  InverseTableOptions options;
  options.encoder_deg = 0.0;
  const auto targets = millkit::ParseCsv("y1_mm,y2_mm\n0,0\n", "t.csv");
  CHECK_THROWS_WITH(ComputeInverseTable(targets, config, options),
                    Contains("InverseTableOptions::encoder_deg: must be > 0"));
  options.encoder_deg = 0.01;
  const auto clash = millkit::ParseCsv("y1_mm,y2_mm,status\n0,0,1\n", "t.csv");
  CHECK_THROWS_WITH(ComputeInverseTable(clash, config, options),
                    "t.csv: column 'status' is an output column; remove it");
  // A header and no target: an empty list or the wrong file.
  CHECK_THROWS_WITH(
      ComputeInverseTable(millkit::ParseCsv("y1_mm,y2_mm\n", "e.csv"), config, options),
      "e.csv: no intermesh targets listed");
}
