// The result CSV of `millkit simulate` (millkit/driveline/result_csv.h): column choice, --every,
// the size estimate and its warning.
#include "millkit/driveline/result_csv.h"

#include <catch2/catch.hpp>
#include <sstream>

#include "millkit/io/input_error.h"
#include "scene_builder.h"

using namespace millkit::driveline;
using Catch::Matchers::Contains;

namespace {
Scene TwoMass() { return testing::TwoMassScene(1.0, 2.0, 1e4, 0.0, 0.0, 1.0, 100.0); }

std::vector<std::string> Names(const std::vector<ResultColumn>& columns) {
  std::vector<std::string> names;
  for (const auto& c : columns) names.push_back(c.name);
  return names;
}

// A sample whose values say where they came from: torque 1x, speed 2x, twist 3x (x = index).
struct FakeSample {
  double torque[1], speed[2], twist[1];
  OutputSample At(int k) {
    torque[0] = 10 + k;
    speed[0] = 20 + k;
    speed[1] = 25 + k;
    twist[0] = 30 + k;
    return {k, 0.5 * k, torque, speed, twist};
  }
};
}  // namespace

TEST_CASE("All result columns are the link torques, speeds and twists in file order", "[csv]") {
  CHECK(Names(AllResultColumns(TwoMass())) ==
        std::vector<std::string>{"shaft", "speed.a", "speed.b", "twist.shaft"});
}

TEST_CASE("Chosen columns come in the order given, time always first", "[csv]") {
  const Scene scene = TwoMass();
  const auto columns = SelectResultColumns(scene, "twist.shaft,speed.a", "--columns");
  CHECK(Names(columns) == std::vector<std::string>{"twist.shaft", "speed.a"});
  CHECK(Names(SelectResultColumns(scene, "time,shaft", "--columns")) ==
        std::vector<std::string>{"shaft"});
  std::ostringstream out;
  ResultCsvWriter writer(&out, "r.csv", columns);
  FakeSample sample;
  writer.Write(sample.At(0));
  writer.Write(sample.At(1));
  CHECK(out.str() == "time,twist.shaft,speed.a\n0,30,20\n0.5,31,21\n");
}

TEST_CASE("A bad column list names the option, the name and the allowed names",
          "[csv][bad_input]") {
  const Scene scene = TwoMass();
  CHECK_THROWS_WITH(SelectResultColumns(scene, "shaft,speed.c", "--columns"),
                    Contains("--columns") && Contains("'speed.c'") &&
                        Contains("allowed: shaft, speed.a, speed.b, twist.shaft"));
  CHECK_THROWS_WITH(SelectResultColumns(scene, "shaft,,speed.a", "--columns"),
                    Contains("--columns") && Contains("empty column name"));
  CHECK_THROWS_WITH(SelectResultColumns(scene, "shaft,shaft", "--columns"),
                    Contains("'shaft' is named twice"));
  CHECK_THROWS_WITH(SelectResultColumns(scene, "shaft,time", "--columns"),
                    Contains("'time'") && Contains("first"));
  CHECK_THROWS_WITH(SelectResultColumns(scene, "time", "--columns"), Contains("no output column"));
}

TEST_CASE("Every N-th sample is written, starting with the first", "[csv]") {
  std::ostringstream out;
  ResultCsvWriter writer(&out, "r.csv", AllResultColumns(TwoMass()), 3);
  FakeSample sample;
  for (int k = 0; k < 7; ++k) writer.Write(sample.At(k));
  CHECK(writer.rows() == 3);
  CHECK(writer.rows() == KeptRows(7, 3));
  CHECK(out.str() ==
        "time,shaft,speed.a,speed.b,twist.shaft\n"
        "0,10,20,25,30\n1.5,13,23,28,33\n3,16,26,31,36\n");
}

TEST_CASE("Kept rows are the ceiling of samples over every", "[csv]") {
  CHECK(KeptRows(1, 1) == 1);
  CHECK(KeptRows(10, 1) == 10);
  CHECK(KeptRows(10, 3) == 4);  // 0, 3, 6, 9
  CHECK(KeptRows(9, 3) == 3);   // 0, 3, 6
  CHECK(KeptRows(0, 5) == 0);
}

TEST_CASE("A failed stream stops the writer with an error naming the file", "[csv]") {
  std::ostringstream out;
  ResultCsvWriter writer(&out, "full.csv", AllResultColumns(TwoMass()));
  out.setstate(std::ios::badbit);
  FakeSample sample;
  CHECK_THROWS_AS(writer.Write(sample.At(0)), millkit::InputError);
  CHECK_THROWS_WITH(writer.Write(sample.At(0)), Contains("full.csv") && Contains("write failed"));
}

TEST_CASE("The size warning appears above 1 GB and names the size and the options", "[csv]") {
  // mill5_bite over 1e4 s at 5 kHz: 5e7 + 1 rows of 14 numbers (time and 13 outputs).
  const long rows = KeptRows(50'000'001, 1);
  CHECK(EstimatedCsvBytes(rows, 14) == rows * 14.0 * kCsvBytesPerNumber);
  const std::string warning = LargeOutputWarning("out.csv", EstimatedCsvBytes(rows, 14));
  CHECK_THAT(warning, Contains("warning: out.csv") && Contains("14.0 GB") && Contains("--every") &&
                          Contains("--columns") && Contains("--kd-only"));
  CHECK(LargeOutputWarning("out.csv", kLargeOutputBytes).empty());
  CHECK_FALSE(LargeOutputWarning("out.csv", 1.01 * kLargeOutputBytes).empty());
  // --every 100 brings the same run under the limit.
  CHECK(LargeOutputWarning("out.csv", EstimatedCsvBytes(KeptRows(50'000'001, 100), 14)).empty());
}
