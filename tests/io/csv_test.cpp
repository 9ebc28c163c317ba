#include "millkit/io/csv.h"

#include <catch2/catch.hpp>

#include "millkit/io/input_error.h"

using Catch::Matchers::Contains;
using millkit::InputError;
using millkit::ParseCsv;

TEST_CASE("A numeric CSV is read with its header and rows", "[csv]") {
  const auto table = ParseCsv("time, a,b\n0,1,2\n# comment\n\n0.5,-1e3,+4\n", "x.csv");
  REQUIRE(table.columns == std::vector<std::string>{"time", "a", "b"});
  REQUIRE(table.rows.size() == 2);
  CHECK(table.rows[1][1] == -1000.0);
  CHECK(table.rows[1][2] == 4.0);
  CHECK(table.line_numbers[1] == 5);
  CHECK(table.Column("b") == 2);
}

TEST_CASE("A non-numeric cell is rejected naming file, line and column", "[csv]") {
  REQUIRE_THROWS_WITH(ParseCsv("time,a\n0,1\n1,abc\n", "rec.csv"),
                      Contains("rec.csv: line 3, column 'a'") && Contains("not a finite number"));
}

TEST_CASE("A NaN cell is rejected", "[csv]") {
  REQUIRE_THROWS_WITH(ParseCsv("time,a\n0,nan\n", "rec.csv"), Contains("line 2, column 'a'"));
}

TEST_CASE("A row with the wrong number of cells is rejected", "[csv]") {
  REQUIRE_THROWS_WITH(ParseCsv("time,a\n0,1,2\n", "rec.csv"), Contains("line 2: 3 cells"));
}

TEST_CASE("A missing column is named", "[csv]") {
  const auto table = ParseCsv("time,a\n0,1\n", "rec.csv");
  REQUIRE_THROWS_WITH(table.Column("b"), Contains("missing column 'b'"));
}

TEST_CASE("A time column that does not increase strictly is rejected with its line", "[csv]") {
  const auto table = ParseCsv("time,a\n0,1\n1,1\n1,2\n", "rec.csv");
  REQUIRE_THROWS_WITH(millkit::RequireStrictlyIncreasing(table, 0),
                      Contains("line 4, column 'time'") && Contains("increase strictly"));
}

TEST_CASE("An empty file is rejected", "[csv]") {
  REQUIRE_THROWS_AS(ParseCsv("\n\n", "e.csv"), InputError);
}

TEST_CASE("A units row is honoured only where it is checked", "[csv]") {
  const auto table = ParseCsv("time,torque\nms,N*m\n0,1\n1,2\n", "t.csv");
  REQUIRE(table.units == std::vector<std::string>{"ms", "N*m"});
  REQUIRE_THROWS_WITH(millkit::RequireUnits(table, {{"time", {"s"}}, {"torque", {"N*m"}}}),
                      Contains("t.csv: line 2 (units row), column 'time'") &&
                          Contains("unit 'ms'") && Contains("takes s"));
  REQUIRE_NOTHROW(millkit::RequireUnits(ParseCsv("time,torque\ns,N*m\n0,1\n", "t.csv"),
                                        {{"time", {"s"}}, {"torque", {"N*m"}}}));
  REQUIRE_THROWS_WITH(millkit::RequireUnits(table, {}), Contains("give no units row"));
}

TEST_CASE("A text table keeps every cell as text, quoted cells unquoted", "[csv]") {
  const auto table = millkit::ParseTextCsv(
      "\xEF\xBB\xBF"
      "file;time;stand\r\n# comment\r\n\"a;b.csv\"; 2026-01-05 ;F1\r\n\r\nc.csv;;\r\n",
      "m.csv");
  REQUIRE(table.columns == std::vector<std::string>{"file", "time", "stand"});
  REQUIRE(table.rows.size() == 2);
  CHECK(table.rows[0] == std::vector<std::string>{"a;b.csv", "2026-01-05", "F1"});
  CHECK(table.rows[1] == std::vector<std::string>{"c.csv", "", ""});
  CHECK(table.line_numbers == std::vector<int>{3, 5});
  CHECK(table.Find("stand") == 2);
  CHECK(table.Find("group") == -1);
  REQUIRE_THROWS_WITH(millkit::ParseTextCsv("file,time\na.csv\n", "m.csv"),
                      Contains("m.csv: line 2: 1 cells, the header has 2"));
}
