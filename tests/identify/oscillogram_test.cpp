// Oscillogram records (SPEC §3): bad records are rejected naming file, row and column.
#include "identify/oscillogram.h"

#include <catch2/catch.hpp>

#include "io/input_error.h"

using namespace millkit::identify;
using millkit::InputError;
using Catch::Matchers::Contains;

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
  CHECK_THROWS_WITH(ParseOscillogram(Record(20, "t,upper"), "rec.csv"), Contains("'time'"));
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
