// Linkage tables (linkage_table.h): the forward table and its CSV writer, the working-range and
// cylinder-range checks, and the inverse table's CSV writer.
#include "millkit/leveller/linkage_table.h"

#include <catch2/catch.hpp>
#include <cmath>

#include "millkit/io/input_error.h"

using namespace millkit::leveller;
using Catch::Matchers::Contains;
using Catch::Matchers::WithinAbs;

namespace {

// 15 significant digits of values below 100 mm.
constexpr double kCellDigitsMm = 1e-12;

}  // namespace

TEST_CASE("The forward table writes the input columns and the linkage's intermesh",
          "[leveller][linkage_table]") {
  const LevellerConfig config = DefaultLevellerConfig();
  const Linkage linkage(config.linkage);
  const auto input =
      millkit::ParseCsv("beta1_deg,note_id,beta2_deg\n0,7,0\n12.5,8,-33\n-70,9,80\n", "in.csv");
  const ForwardTable table = ComputeForwardTable(input, config, LinkageDrive::kEccentric);
  REQUIRE(table.intermesh.size() == 3);
  const auto written = millkit::ParseCsv(FormatForwardTable(table), "out.csv");
  REQUIRE(written.columns ==
          std::vector<std::string>{"beta1_deg", "note_id", "beta2_deg", "y1_mm", "y2_mm", "y3_mm"});
  for (std::size_t r = 0; r < input.rows.size(); ++r) {
    Intermesh<double> y{};
    REQUIRE(linkage.Forward(input.rows[r][0], input.rows[r][2], &y));
    CHECK(written.rows[r][1] == input.rows[r][1]);
    CHECK_THAT(written.rows[r][3], WithinAbs(y.y1, kCellDigitsMm));
    CHECK_THAT(written.rows[r][4], WithinAbs(y.y2, kCellDigitsMm));
    CHECK_THAT(written.rows[r][5], WithinAbs(y.y3, kCellDigitsMm));
    CHECK_THAT(written.rows[r][5], WithinAbs(2.0 * written.rows[r][4] - written.rows[r][3], 1e-9));
  }
  // The SPEC's check value at beta = (0, 0).
  CHECK_THAT(written.rows[0][3], WithinAbs(-0.2080, 5e-5));
}

TEST_CASE("The forward table refuses inputs outside the working and cylinder ranges",
          "[leveller][linkage_table]") {
  const LevellerConfig config = DefaultLevellerConfig();
  const auto angles = millkit::ParseCsv("beta1_deg,beta2_deg\n0,0\n10,-95\n", "a.csv");
  REQUIRE_THROWS_WITH(ComputeForwardTable(angles, config, LinkageDrive::kEccentric),
                      "a.csv:3: column 'beta2_deg' = -95 outside the working range [-90, 90] deg");
  const auto lengths = millkit::ParseCsv("ah_mm,bg_mm\n540.913,540.913\n500,550\n", "l.csv");
  REQUIRE_THROWS_WITH(ComputeForwardTable(lengths, config, LinkageDrive::kHydraulic),
                      Contains("l.csv:3: (ah_mm, bg_mm) = (500, 550) outside the cylinder ranges "
                               "[525.913, 555.913] x [525.913, 555.913] mm"));
  const auto clash = millkit::ParseCsv("beta1_deg,beta2_deg,y2_mm\n0,0,1\n", "c.csv");
  REQUIRE_THROWS_WITH(ComputeForwardTable(clash, config, LinkageDrive::kEccentric),
                      "c.csv: column 'y2_mm' is an output column; remove it");
  // A header and no row: an empty list or the wrong file, not an empty table.
  REQUIRE_THROWS_WITH(ComputeForwardTable(millkit::ParseCsv("beta1_deg,beta2_deg\n", "e.csv"),
                                          config, LinkageDrive::kEccentric),
                      "e.csv: no eccentric angles listed");
  REQUIRE_THROWS_WITH(ComputeForwardTable(millkit::ParseCsv("ah_mm,bg_mm\n", "h.csv"), config,
                                          LinkageDrive::kHydraulic),
                      "h.csv: no cylinder lengths listed");
  // The hydraulic drive reads the cylinder lengths, not the angles.
  REQUIRE_THROWS_AS(ComputeForwardTable(angles, config, LinkageDrive::kHydraulic),
                    millkit::InputError);
  CHECK_NOTHROW(CheckWorkingRange(config.linkage, -90.0, 90.0, "here"));
  CHECK_THROWS_WITH(CheckWorkingRange(config.linkage, 90.5, 0.0, "here"),
                    Contains("here: column 'beta1_deg' = 90.5"));
}

TEST_CASE("The inverse writer puts each row's values, nearest pair and status in its columns",
          "[leveller][linkage_table]") {
  InverseTable table;
  table.input = millkit::ParseCsv("y1_mm,y2_mm\n1,2\n40,0\n", "t.csv");
  table.drive = LinkageDrive::kEccentric;
  InverseRow ok;
  ok.beta1_deg = 12.25;
  ok.beta2_deg = -3.5;
  ok.y3_mm = 3.0;
  ok.residual_mm = 1e-12;
  ok.accuracy_mm = 0.0025;
  ok.nearest_y1_mm = 1.0;
  ok.nearest_y2_mm = 2.0;
  InverseRow unreachable;
  unreachable.status = "unreachable";
  unreachable.nearest_y1_mm = 29.5;
  unreachable.nearest_y2_mm = 0.25;
  table.rows = {ok, unreachable};
  CHECK(table.NotOkCount() == 1);
  CHECK(FormatInverseTable(table) ==
        "y1_mm,y2_mm,beta1_deg,beta2_deg,y3_mm,residual_mm,accuracy_mm,nearest_y1_mm,"
        "nearest_y2_mm,status\n"
        "1,2,12.25,-3.5,3,1e-12,0.0025,1,2,ok\n"
        "40,0,nan,nan,nan,nan,nan,29.5,0.25,unreachable\n");
  table.drive = LinkageDrive::kHydraulic;
  table.rows[0].ah_mm = 530.5;
  table.rows[0].bg_mm = 550.125;
  CHECK(FormatInverseTable(table) ==
        "y1_mm,y2_mm,ah_mm,bg_mm,y3_mm,residual_mm,nearest_y1_mm,nearest_y2_mm,status\n"
        "1,2,530.5,550.125,3,1e-12,1,2,ok\n"
        "40,0,nan,nan,nan,nan,29.5,0.25,unreachable\n");
}
