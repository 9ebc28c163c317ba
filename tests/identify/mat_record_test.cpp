// MATLAB records (issue 13, item 2): MAT v5 and v7.3 files written here with libmatio read the
// same record as the CSV, at the top level or inside a struct; what cannot be a record is an
// error naming the file and the variable.
#include "millkit/identify/mat_record.h"

#include <matio.h>

#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "fit_fixture.h"
#include "millkit/identify/fit.h"
#include "millkit/identify/oscillogram.h"
#include "millkit/io/input_error.h"
#include "support/run_cli.h"

namespace millkit::identify {
namespace {

using Catch::Matchers::Contains;
using millkit::testing::ScratchDir;
using namespace millkit::identify::testing;

// A column vector of doubles (or singles) named `name`, owned by the caller.
matvar_t* Vector(const std::string& name, const std::vector<double>& values, bool single = false) {
  size_t dims[2] = {values.size(), 1};
  if (single) {
    std::vector<float> narrow(values.begin(), values.end());
    return Mat_VarCreate(name.c_str(), MAT_C_SINGLE, MAT_T_SINGLE, 2, dims, narrow.data(), 0);
  }
  return Mat_VarCreate(name.c_str(), MAT_C_DOUBLE, MAT_T_DOUBLE, 2, dims,
                       const_cast<double*>(values.data()), 0);
}

void Write(mat_t* file, matvar_t* variable) {
  REQUIRE(variable != nullptr);
  REQUIRE(Mat_VarWrite(file, variable, MAT_COMPRESSION_NONE) == 0);
  Mat_VarFree(variable);
}

// The record as top-level vectors `time_name`, then one per channel.
void WriteTopLevel(const std::filesystem::path& path, mat_ft version, const Oscillogram& record,
                   const std::string& time_name = "time") {
  mat_t* file = Mat_CreateVer(path.c_str(), nullptr, version);
  REQUIRE(file != nullptr);
  Write(file, Vector(time_name, record.time_s));
  for (size_t c = 0; c < record.channels.size(); ++c) {
    Write(file, Vector(record.channels[c], record.values[c]));
  }
  Mat_Close(file);
}

// The record as the fields of a 1×1 struct `name` (time field `t`).
matvar_t* RecordStruct(const std::string& name, const Oscillogram& record) {
  std::vector<std::string> names = {"t"};
  names.insert(names.end(), record.channels.begin(), record.channels.end());
  std::vector<const char*> fields;
  for (const auto& n : names) fields.push_back(n.c_str());
  fields.push_back(nullptr);
  size_t dims[2] = {1, 1};
  matvar_t* s = Mat_VarCreateStruct2(name.c_str(), 2, dims, fields.data());
  Mat_VarSetStructFieldByName(s, "t", 0, Vector("t", record.time_s));
  for (size_t c = 0; c < record.channels.size(); ++c) {
    Mat_VarSetStructFieldByName(s, record.channels[c].c_str(), 0,
                                Vector(record.channels[c], record.values[c]));
  }
  return s;
}

// The same channels by name (a v7.3 file, which is HDF5, lists its variables alphabetically).
void CheckSame(const Oscillogram& expected, const Oscillogram& record) {
  REQUIRE(record.channels.size() == expected.channels.size());
  CHECK(record.time_s == expected.time_s);
  for (size_t c = 0; c < expected.channels.size(); ++c) {
    INFO(expected.channels[c]);
    const int j = record.ChannelIndex(expected.channels[c]);
    REQUIRE(j >= 0);
    CHECK(record.values[j] == expected.values[c]);
  }
}

}  // namespace

TEST_CASE("MAT v5 and v7.3 records read the same record as the CSV and fit to the same values") {
  ScratchDir dir;
  const Oscillogram csv = Mill5Record(0.01, 12, 0.0, 3);
  for (const auto version : {MAT_FT_MAT5, MAT_FT_MAT73}) {
    const std::string label = version == MAT_FT_MAT5 ? "v5" : "v7.3";
    INFO(label);
    const auto path = dir / ("rec_" + label + ".mat");
    WriteTopLevel(path, version, csv);
    const Oscillogram record = LoadOscillogram(path);
    CheckSame(csv, record);
    CHECK(record.notes.empty());
  }
  // Identical numbers make identical fits: one fit shows the record reaches Fit intact.
  auto scene = Mill5Scene();
  const FitConfig config = Mill5Config(csv, &scene);
  CheckSameFit(Fit(scene, csv, config, FitOptions{}),
               Fit(scene, LoadOscillogram(dir / "rec_v7.3.mat"), config, FitOptions{}));
}

TEST_CASE(
    "a logger CSV with BOM, semicolons, decimal commas and a kN*m units row fits like the "
    "plain CSV") {
  const Oscillogram csv = Mill5Record(0.01, 12, 0.0, 3);
  // Values in kN*m, 17 significant digits, decimal comma; a coil-ID text column; CRLF.
  std::string text = "\xEF\xBB\xBF\"Time [s]\";coil";
  for (const auto& name : csv.channels) {
    text += ";\"";
    text += name;
    text += '"';
  }
  text += "\r\ns;";
  for (size_t c = 0; c < csv.channels.size(); ++c) text += ";kN*m";
  text += "\r\n";
  const auto number = [](double v) {
    char cell[64];
    std::snprintf(cell, sizeof(cell), "%.17g", v);
    std::string s = cell;
    std::replace(s.begin(), s.end(), '.', ',');
    return s;
  };
  for (size_t k = 0; k < csv.time_s.size(); ++k) {
    text += number(csv.time_s[k]);
    text += ";C-4711";
    for (const auto& column : csv.values) {
      text += ';';
      text += number(column[k] / 1e3);
    }
    text += "\r\n";
  }
  const Oscillogram logger = ParseOscillogram(text, "logger.csv");
  REQUIRE(logger.time_s == csv.time_s);
  auto scene = Mill5Scene();
  const FitConfig config = Mill5Config(csv, &scene);
  auto logger_scene = Mill5Scene();
  const FitConfig logger_config = Mill5Config(logger, &logger_scene);  // unit from the units row
  for (const auto& c : logger_config.channels) CHECK(c.unit.name == "kN*m");
  // v / 1e3 printed with 17 digits and read back times 1e3 is v within an ulp or two: the fits
  // agree within their convergence tolerance.
  CheckSameFit(Fit(scene, csv, config, FitOptions{}),
               Fit(logger_scene, logger, logger_config, FitOptions{}), 1e-7);
}

TEST_CASE("a MAT record inside a struct, with other variables skipped with a note") {
  ScratchDir dir;
  const Oscillogram csv = Mill5Record(0.01, 12, 0.0, 3);
  for (const auto version : {MAT_FT_MAT5, MAT_FT_MAT73}) {
    INFO((version == MAT_FT_MAT5 ? "v5" : "v7.3"));
    const auto path = dir / "struct.mat";
    mat_t* file = Mat_CreateVer(path.c_str(), nullptr, version);
    REQUIRE(file != nullptr);
    Write(file, RecordStruct("bite", csv));
    Write(file, Vector("calibration", {1.0, 2.0, 3.0}));
    Mat_Close(file);
    const Oscillogram record = LoadOscillogram(path);
    CheckSame(csv, record);
    std::filesystem::remove(path);
  }
  SECTION("a field of another length, a single-precision channel, --time-column") {
    const auto path = dir / "mixed.mat";
    mat_t* file = Mat_CreateVer(path.c_str(), nullptr, MAT_FT_MAT5);
    Write(file, Vector("zeit", csv.time_s));
    Write(file, Vector("upper_spindle", csv.values[0], true));
    Write(file, Vector("short", {1.0, 2.0}));
    Mat_Close(file);
    CHECK_THROWS_WITH(LoadOscillogram(path),
                      Contains("mixed.mat") && Contains("no time vector") && Contains("zeit"));
    const Oscillogram record = LoadOscillogram(path, {"zeit"});
    REQUIRE(record.channels == std::vector<std::string>{"upper_spindle"});
    for (size_t k = 0; k < csv.time_s.size(); ++k) {
      CHECK(record.values[0][k] == static_cast<double>(static_cast<float>(csv.values[0][k])));
    }
    REQUIRE(record.notes.size() == 1);
    CHECK_THAT(record.notes[0],
               Contains("'short'") && Contains("2 samples") && Contains("skipped"));
  }
}

TEST_CASE("MAT files that cannot be a record are errors naming the file and the variable") {
  ScratchDir dir;
  const Oscillogram csv = Mill5Record(0.01, 12, 0.0, 3);
  const auto path = dir / "bad.mat";
  const auto write = [&](const std::vector<matvar_t*>& variables) {
    std::filesystem::remove(path);
    mat_t* file = Mat_CreateVer(path.c_str(), nullptr, MAT_FT_MAT5);
    REQUIRE(file != nullptr);
    for (auto* v : variables) Write(file, v);
    Mat_Close(file);
  };
  SECTION("not a MAT file") {
    millkit::testing::WriteText(path, "time,upper\n0,1\n");
    CHECK_THROWS_WITH(LoadOscillogram(path), Contains("bad.mat") && Contains("MAT v5 or v7.3"));
  }
  SECTION("two structs holding a time vector") {
    write({RecordStruct("a", csv), RecordStruct("b", csv)});
    CHECK_THROWS_WITH(LoadOscillogram(path), Contains("'a' and 'b' both hold a time vector"));
  }
  SECTION("a time that does not increase, with its 1-based index") {
    Oscillogram bad = csv;
    bad.time_s[10] = bad.time_s[9];
    WriteTopLevel(path, MAT_FT_MAT5, bad);
    CHECK_THROWS_WITH(LoadOscillogram(path), Contains("time(11)") && Contains("increase"));
  }
  SECTION("a NaN in a channel, with its index") {
    Oscillogram bad = csv;
    bad.values[1][4] = std::nan("");
    WriteTopLevel(path, MAT_FT_MAT5, bad);
    CHECK_THROWS_WITH(LoadOscillogram(path),
                      Contains(csv.channels[1] + "(5)") && Contains("not a finite number"));
  }
  SECTION("a time but no channel") {
    write({Vector("time", csv.time_s), Vector("other", {1.0})});
    CHECK_THROWS_WITH(LoadOscillogram(path), Contains("no channel"));
  }
  SECTION("too few samples") {
    write({Vector("time", {0.0, 1.0}), Vector("x", {0.0, 1.0})});
    CHECK_THROWS_WITH(LoadOscillogram(path), Contains("2 samples") && Contains("at least"));
  }
}

TEST_CASE("identify reads a .mat record with logger time from the command line") {
  ScratchDir dir;
  Oscillogram csv = Mill5Record(0.01, 12, 0.0, 3);
  for (double& t : csv.time_s) t += 7.25;
  WriteTopLevel(dir / "rec.mat", MAT_FT_MAT73, csv);
  std::string config = millkit::testing::ReadText(
      millkit::testing::SourcePath("datasets/records/mill5_two_spindles.fit.toml"));
  const std::string window = "window = [0.0, 0.3]";
  REQUIRE(config.find(window) != std::string::npos);
  config.replace(config.find(window), window.size(), "window = [7.25, 7.55]");
  millkit::testing::WriteText(dir / "fit.toml", config);
  const auto run = millkit::testing::RunMillkit(
      "identify '" + millkit::testing::SourcePath("datasets/scenes/mill5_bite.toml") +
      "' --data '" + (dir / "rec.mat").string() + "' --config '" + (dir / "fit.toml").string() +
      "' --out '" + (dir / "fit.json").string() + "' --quiet");
  INFO(run.stderr_text);
  CHECK(run.exit_code == 0);
  CHECK_THAT(run.stdout_text, Contains("rec.mat") && Contains("time origin: record time 7.25 s"));
}

}  // namespace millkit::identify
