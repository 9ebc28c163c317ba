// Oscillogram records (SPEC §3): bad records are rejected naming file, row and column.
#include "millkit/identify/oscillogram.h"

#include <algorithm>
#include <catch2/catch.hpp>

#include "millkit/io/csv.h"
#include "millkit/io/input_error.h"

using namespace millkit::identify;
using Catch::Matchers::Contains;
using millkit::InputError;

namespace {

// A valid record of `rows` samples at 1 kHz with one channel.
std::string Record(int rows, const std::string& header = "time,upper") {
  std::string text = header + "\n";
  for (int k = 0; k < rows; ++k) text += std::to_string(k * 0.001) + "," + std::to_string(k) + "\n";
  return text;
}

}  // namespace

TEST_CASE("A valid record loads its time column and channels") {
  const Oscillogram record = ParseOscillogram(Record(20), "rec.csv");
  CHECK(record.channels == std::vector<std::string>{"upper"});
  CHECK(record.time_s.size() == 20);
  CHECK(record.values[0][19] == 19.0);
  CHECK(record.ChannelIndex("upper") == 0);
  CHECK(record.ChannelIndex("lower") == -1);
}

TEST_CASE("A non-numeric cell is rejected with its line and column") {
  std::string text = Record(20);
  text.replace(text.find("0.005000,5"), 10, "0.005000,abc");
  CHECK_THROWS_WITH(ParseOscillogram(text, "rec.csv"),
                    Contains("rec.csv") && Contains("line") && Contains("upper"));
}

TEST_CASE("A NaN cell is rejected") {
  std::string text = Record(20) + "0.5,nan\n";
  CHECK_THROWS_WITH(ParseOscillogram(text, "rec.csv"), Contains("rec.csv") && Contains("line 22"));
}

TEST_CASE("A time that does not increase is rejected with its line") {
  std::string text = Record(20) + "0.0100,3\n";
  CHECK_THROWS_WITH(ParseOscillogram(text, "rec.csv"),
                    Contains("rec.csv") && Contains("line 22") && Contains("increas"));
}

TEST_CASE("A record whose first column is not time, or without channels, is rejected") {
  CHECK_THROWS_WITH(ParseOscillogram(Record(20, "x,upper"), "rec.csv"),
                    Contains("line 1") && Contains("no time column") && Contains("'time'"));
  std::string only_time = "time\n";
  for (int k = 0; k < 20; ++k) only_time += std::to_string(k) + "\n";
  CHECK_THROWS_WITH(ParseOscillogram(only_time, "rec.csv"), Contains("no channel"));
}

TEST_CASE("A record with too few samples is rejected") {
  CHECK_THROWS_WITH(ParseOscillogram(Record(kMinRecordSamples - 1), "rec.csv"),
                    Contains("at least " + std::to_string(kMinRecordSamples)));
}

TEST_CASE("A record survives a round trip through its CSV text exactly") {
  const Oscillogram record = ParseOscillogram(Record(20), "rec.csv");
  const Oscillogram again = ParseOscillogram(FormatOscillogram(record), "again.csv");
  CHECK(again.time_s == record.time_s);
  CHECK(again.values == record.values);
}

TEST_CASE("Records fitted together are named by file stem, numbered where two stems agree") {
  std::vector<Oscillogram> records(3);
  records[0].source = "shift1/bite.csv";
  records[1].source = "shift2/bite.csv";
  records[2].source = "/data/pass3.csv";
  CHECK(RecordLabels(records) == std::vector<std::string>{"bite#1", "bite#2", "pass3"});
}

namespace {

// The same record in the plain dialect and rewritten by `transform` of each data row's cells.
struct Dialect {
  std::string text;
  Oscillogram plain;
};

Oscillogram Plain() {
  std::string text = "time,upper,lower\n";
  for (int k = 0; k < 20; ++k) {
    text += std::to_string(7.25 + k * 0.0005) + "," + std::to_string(1000.5 * k - 3.25) + "," +
            std::to_string(-250.125 * k) + "\n";
  }
  return ParseOscillogram(text, "plain.csv");
}

// Writes the plain record's numbers with `separator`, a decimal comma when asked.
std::string Rewrite(const Oscillogram& plain, const std::string& header, char separator,
                    bool decimal_comma, const std::string& units_row = "",
                    const std::string& extra_cell = "", const std::string& line_end = "\n") {
  std::string text = header + line_end;
  if (!units_row.empty()) text += units_row + line_end;
  const auto number = [&](double v) {
    std::string s = std::to_string(v);
    if (decimal_comma) std::replace(s.begin(), s.end(), '.', ',');
    return s;
  };
  for (size_t k = 0; k < plain.time_s.size(); ++k) {
    text += number(plain.time_s[k]);
    for (const auto& column : plain.values) text += separator + number(column[k]);
    text += extra_cell + line_end;
  }
  return text;
}

void CheckSame(const Oscillogram& a, const Oscillogram& b) {
  REQUIRE(a.channels == b.channels);
  CHECK(a.time_s == b.time_s);
  CHECK(a.values == b.values);
}

}  // namespace

TEST_CASE("logger dialects: each feature alone reads the same record") {
  const Oscillogram plain = Plain();
  SECTION("a byte-order mark") {
    CheckSame(plain, ParseOscillogram(
                         "\xEF\xBB\xBF" + Rewrite(plain, "time,upper,lower", ',', false), "b.csv"));
  }
  SECTION("semicolons") {
    CheckSame(plain, ParseOscillogram(Rewrite(plain, "time;upper;lower", ';', false), "s.csv"));
  }
  SECTION("a decimal comma with semicolons") {
    CheckSame(plain, ParseOscillogram(Rewrite(plain, "time;upper;lower", ';', true), "d.csv"));
  }
  SECTION("tabs") {
    CheckSame(plain, ParseOscillogram(Rewrite(plain, "time\tupper\tlower", '\t', false), "t.csv"));
  }
  SECTION("quoted headers") {
    CheckSame(plain, ParseOscillogram(Rewrite(plain, "\"time\",\"upper\",\"lower\"", ',', false),
                                      "q.csv"));
  }
  SECTION("a units row") {
    const auto record =
        ParseOscillogram(Rewrite(plain, "time,upper,lower", ',', false, "s,N*m,N*m"), "u.csv");
    CheckSame(plain, record);
    CHECK(record.units == std::vector<std::string>{"N*m", "N*m"});
  }
  SECTION("a trailing separator and CRLF") {
    CheckSame(plain,
              ParseOscillogram(Rewrite(plain, "time,upper,lower,", ',', false, "", ",", "\r\n"),
                               "c.csv"));
  }
  SECTION("a text column is skipped with a note") {
    std::string text = "time,coil,upper,lower\n";
    for (size_t k = 0; k < plain.time_s.size(); ++k) {
      text += std::to_string(plain.time_s[k]) + ",C-" + std::to_string(4711 + k) + "," +
              std::to_string(plain.values[0][k]) + "," + std::to_string(plain.values[1][k]) + "\n";
    }
    const auto record = ParseOscillogram(text, "x.csv");
    CheckSame(plain, record);
    REQUIRE(record.notes.size() == 1);
    CHECK_THAT(record.notes[0], Contains("coil") && Contains("skipped"));
  }
  SECTION("time named t, Time, time_s or Time [s]") {
    for (const std::string name : {"t", "Time", "time_s", "Time [s]"}) {
      CheckSame(plain,
                ParseOscillogram(Rewrite(plain, name + ",upper,lower", ',', false), "n.csv"));
    }
  }
  SECTION("time in ms by its units row") {
    Oscillogram ms = plain;
    for (double& t : ms.time_s) t *= 1000.0;
    const auto record =
        ParseOscillogram(Rewrite(ms, "time,upper,lower", ',', false, "ms,N*m,N*m"), "m.csv");
    for (size_t k = 0; k < plain.time_s.size(); ++k)
      CHECK(record.time_s[k] == Approx(plain.time_s[k]).epsilon(1e-15));
  }
}

TEST_CASE("logger dialects: BOM semicolons decimal comma and units row together read the same") {
  const Oscillogram plain = Plain();
  const std::string text = "\xEF\xBB\xBF" + Rewrite(plain, "\"Time [s]\";\"upper\";\"lower\";", ';',
                                                    true, "s;kN*m;kN*m;", ";", "\r\n");
  const auto record = ParseOscillogram(text, "all.csv");
  CheckSame(plain, record);
  CHECK(record.units == std::vector<std::string>{"kN*m", "kN*m"});
}

TEST_CASE("logger dialects: what is ambiguous is an error naming the line") {
  CHECK_THROWS_WITH(ParseOscillogram("time;upper,lower\n0;1,2\n", "m.csv"),
                    Contains("m.csv: line 1") && Contains("mixes the separators"));
  std::string two_times = "time,t,upper\n";
  for (int k = 0; k < 20; ++k) two_times += std::to_string(k) + "," + std::to_string(k) + ",1\n";
  CHECK_THROWS_WITH(ParseOscillogram(two_times, "two.csv"),
                    Contains("two.csv: line 1") && Contains("two time columns"));
  std::string bad_unit = "time,upper\nmin,N*m\n";
  for (int k = 0; k < 20; ++k) bad_unit += std::to_string(k) + ",1\n";
  CHECK_THROWS_WITH(ParseOscillogram(bad_unit, "u.csv"), Contains("time unit 'min'"));
  // A decimal comma in a comma-separated file is a cell count error, not a silent misread.
  CHECK_THROWS_WITH(ParseOscillogram("time,upper\n0,1,5\n", "c.csv"), Contains("line 2: 3 cells"));
}

TEST_CASE("iba ASCII export: signal IDs, names, units and info rows read the same record") {
  const Oscillogram plain = Plain();
  // Tab separated with a decimal comma, as ibaAnalyzer writes it; a text signal is skipped.
  std::string text = "\t[0:1]\t[0:2]\t[3:12]_text\nTime\tupper\tlower\tcoil\ns\tkNm\tkN*m\t\n";
  text += "Plant: hot strip mill 2\t\t\t\nOperator: shift B\t\t\t\n";
  for (size_t k = 0; k < plain.time_s.size(); ++k) {
    std::string row = std::to_string(plain.time_s[k]) + "\t" + std::to_string(plain.values[0][k]) +
                      "\t" + std::to_string(plain.values[1][k]) + "\tC-4711";
    std::replace(row.begin(), row.end(), '.', ',');
    text += row + "\n";
  }
  const auto record = ParseOscillogram(text, "iba.txt");
  CheckSame(plain, record);
  CHECK(record.ids == std::vector<std::string>{"[0:1]", "[0:2]"});
  CHECK(record.units == std::vector<std::string>{"kNm", "kN*m"});
  CHECK(record.ChannelIndex("[0:2]") == 1);
  CHECK(record.ChannelIndex("lower") == 1);
  CHECK(record.ChannelIndex("[0:3]") == -1);
  REQUIRE(record.notes.size() == 2);
  CHECK_THAT(record.notes[0], Contains("iba.txt: line 4-5") && Contains("info rows skipped"));
  CHECK_THAT(record.notes[1], Contains("coil") && Contains("skipped"));

  SECTION("without names the IDs name the channels") {
    std::string bare = "time,[0:1],[0:2]\n";
    for (size_t k = 0; k < plain.time_s.size(); ++k) {
      bare += std::to_string(plain.time_s[k]) + "," + std::to_string(plain.values[0][k]) + "," +
              std::to_string(plain.values[1][k]) + "\n";
    }
    const auto ids_only = ParseOscillogram(bare, "bare.txt");
    CHECK(ids_only.channels == std::vector<std::string>{"[0:1]", "[0:2]"});
    CHECK(ids_only.values == plain.values);
  }
}

TEST_CASE("iba signal IDs: analog, digital and text forms, nothing else") {
  using millkit::IsSignalId;
  CHECK(IsSignalId("[3:12]"));
  CHECK(IsSignalId("[0.7]"));
  CHECK(IsSignalId("[3:12]_text"));
  CHECK_FALSE(IsSignalId("[3.12]_text"));
  CHECK_FALSE(IsSignalId("[3:]"));
  CHECK_FALSE(IsSignalId("[a:1]"));
  CHECK_FALSE(IsSignalId("3:12"));
  CHECK_FALSE(IsSignalId("[3:12] x"));
}

TEST_CASE("the option --time-column chooses the time column, and the others become channels") {
  const Oscillogram plain = Plain();
  const std::string text = Rewrite(plain, "Zeit,upper,lower", ',', false);
  CHECK_THROWS_WITH(ParseOscillogram(text, "z.csv"), Contains("no time column") &&
                                                         Contains("RecordOptions::time_column") &&
                                                         Contains("Zeit"));
  CheckSame(plain, ParseOscillogram(text, "z.csv", {"Zeit"}));
  CHECK_THROWS_WITH(ParseOscillogram(text, "z.csv", {"time"}),
                    Contains("z.csv: line 1") &&
                        Contains("no column 'time' (RecordOptions::time_column)") &&
                        Contains("seen: Zeit, upper, lower"));
  // Two time-like names: the option settles which one is time; the other is a channel.
  std::string two = "time,t,upper\n";
  for (int k = 0; k < 20; ++k) two += std::to_string(k) + "," + std::to_string(2 * k) + ",1\n";
  CHECK_THROWS_WITH(ParseOscillogram(two, "two.csv"), Contains("RecordOptions::time_column"));
  const auto chosen = ParseOscillogram(two, "two.csv", {"t"});
  CHECK(chosen.time_s[3] == 6.0);
  CHECK(chosen.channels == std::vector<std::string>{"time", "upper"});
}

TEST_CASE("a plain table with two rows without numbers after its header is refused") {
  std::string text = "time,upper\ns,N*m\nsecond,row\n";
  for (int k = 0; k < 20; ++k) text += std::to_string(k) + ",1\n";
  CHECK_THROWS_WITH(ParseOscillogram(text, "r.csv"),
                    Contains("r.csv: line 3") && Contains("at most one units row"));
}
