// MATLAB records (issue 13, item 2): MAT v5 and v7.3 files written here with libmatio read the
// same record as the CSV, at the top level or inside a struct; what cannot be a record is an
// error naming the file and the variable.
#include "millkit/identify/mat_record.h"

#include <matio.h>
#include <zlib.h>

#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <iterator>
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

void Write(mat_t* file, matvar_t* variable, matio_compression compression = MAT_COMPRESSION_NONE) {
  REQUIRE(variable != nullptr);
  REQUIRE(Mat_VarWrite(file, variable, compression) == 0);
  Mat_VarFree(variable);
}

// The record as top-level vectors `time_name`, then one per channel.
void WriteTopLevel(const std::filesystem::path& path, mat_ft version, const Oscillogram& record,
                   const std::string& time_name = "time",
                   matio_compression compression = MAT_COMPRESSION_NONE) {
  mat_t* file = Mat_CreateVer(path.c_str(), nullptr, version);
  REQUIRE(file != nullptr);
  Write(file, Vector(time_name, record.time_s), compression);
  for (size_t c = 0; c < record.channels.size(); ++c) {
    Write(file, Vector(record.channels[c], record.values[c]), compression);
  }
  Mat_Close(file);
}

std::string ReadBytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void WriteBytes(const std::filesystem::path& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

std::uint32_t Word(const std::string& bytes, size_t at) {
  std::uint32_t w = 0;
  for (int i = 3; i >= 0; --i) w = w << 8 | static_cast<unsigned char>(bytes[at + i]);
  return w;
}

void SetWord(std::string* bytes, size_t at, std::uint32_t w) {
  for (int i = 0; i < 4; ++i) (*bytes)[at + i] = static_cast<char>((w >> (8 * i)) & 0xFF);
}

// The first variable of a compressed (little-endian) v5 file, inflated: its miMATRIX tag and
// contents.
std::string InflateFirst(const std::string& file) {
  REQUIRE(Word(file, 128) == 15);  // miCOMPRESSED
  const uLong compressed = Word(file, 132);
  std::string inflated(8, '\0');
  uLongf size = 8;
  // The tag first, for the size; then the whole variable.
  uncompress(reinterpret_cast<Bytef*>(inflated.data()), &size,
             reinterpret_cast<const Bytef*>(file.data() + 136), compressed);
  inflated.resize(8 + Word(inflated, 4));
  size = inflated.size();
  REQUIRE(uncompress(reinterpret_cast<Bytef*>(inflated.data()), &size,
                     reinterpret_cast<const Bytef*>(file.data() + 136), compressed) == Z_OK);
  return inflated;
}

// `file` with its first (compressed) variable replaced by `variable`, deflated again.
std::string ReplaceFirst(const std::string& file, const std::string& variable) {
  uLongf size = compressBound(variable.size());
  std::string deflated(size, '\0');
  REQUIRE(compress(reinterpret_cast<Bytef*>(deflated.data()), &size,
                   reinterpret_cast<const Bytef*>(variable.data()), variable.size()) == Z_OK);
  deflated.resize(size);
  std::string out = file.substr(0, 128);
  out.append(8, '\0');
  SetWord(&out, 128, 15);
  SetWord(&out, 132, static_cast<std::uint32_t>(deflated.size()));
  out += deflated;
  out += file.substr(136 + Word(file, 132));
  return out;
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

TEST_CASE("compressed MAT v5 records read the same record as uncompressed ones") {
  ScratchDir dir;
  const Oscillogram csv = Mill5Record(0.01, 12, 0.0, 3);
  WriteTopLevel(dir / "top.mat", MAT_FT_MAT5, csv, "time", MAT_COMPRESSION_ZLIB);
  CheckSame(csv, LoadOscillogram(dir / "top.mat"));
  mat_t* file = Mat_CreateVer((dir / "struct.mat").c_str(), nullptr, MAT_FT_MAT5);
  REQUIRE(file != nullptr);
  Write(file, RecordStruct("rec", csv), MAT_COMPRESSION_ZLIB);
  Write(file, Vector("other", {1.0, 2.0}), MAT_COMPRESSION_ZLIB);
  Mat_Close(file);
  CheckSame(csv, LoadOscillogram(dir / "struct.mat"));
}

// Sizes a damaged file declares but does not hold, which libmatio would allocate before finding
// out (gigabytes: the fuzzer's findings), are refused first, naming the byte and the rule.
TEST_CASE("damaged MAT v5 files are refused before libmatio reads them") {
  ScratchDir dir;
  const Oscillogram csv = Mill5Record(0.01, 12, 0.0, 3);
  const auto path = dir / "damaged.mat";
  // Uncompressed: the first variable's tag at byte 128, its array flags' tag at 136 (data at
  // 144), its dimensions' tag at 152 (rows at 160, columns at 164).
  WriteTopLevel(dir / "plain.mat", MAT_FT_MAT5, csv);
  const std::string plain = ReadBytes(dir / "plain.mat");
  REQUIRE(Word(plain, 128) == 14);  // miMATRIX
  REQUIRE(Word(plain, 160) == csv.time_s.size());
  // Compressed: the first variable inflated, with the same layout from byte 0.
  WriteTopLevel(dir / "zipped.mat", MAT_FT_MAT5, csv, "time", MAT_COMPRESSION_ZLIB);
  const std::string zipped = ReadBytes(dir / "zipped.mat");
  const std::string inflated = InflateFirst(zipped);
  REQUIRE(Word(inflated, 32) == csv.time_s.size());
  // The untouched round trip reads.
  WriteBytes(path, ReplaceFirst(zipped, inflated));
  CheckSame(csv, LoadOscillogram(path));

  SECTION("a variable larger than the file") {
    std::string bytes = plain;
    SetWord(&bytes, 132, 0x7FFFFFF0);
    WriteBytes(path, bytes);
    CHECK_THROWS_WITH(LoadOscillogram(path), Contains("damaged.mat: damaged MAT file") &&
                                                 Contains("declares") && Contains("(byte 128)"));
  }
  SECTION("dimensions that claim more elements than the data hold") {
    std::string bytes = plain;
    SetWord(&bytes, 160, 0x7FFFFFFF);
    WriteBytes(path, bytes);
    CHECK_THROWS_WITH(LoadOscillogram(path),
                      Contains("the dimensions claim 2147483647 elements") && Contains("byte"));
  }
  SECTION("a negative dimension") {
    std::string bytes = plain;
    SetWord(&bytes, 164, 0xFFFFFFFF);
    WriteBytes(path, bytes);
    CHECK_THROWS_WITH(LoadOscillogram(path), Contains("a negative dimension (byte 164)"));
  }
  SECTION("dimensions inside a compressed variable") {
    std::string variable = inflated;
    SetWord(&variable, 32, 0x10000000);
    WriteBytes(path, ReplaceFirst(zipped, variable));
    CHECK_THROWS_WITH(LoadOscillogram(path),
                      Contains("the dimensions claim 268435456 elements") &&
                          Contains("of the variable compressed at byte 128"));
  }
  // The fuzzer's finding of 2026-11-27 (a function handle; libmatio asked for 2.1 GB, a pointer
  // for each of the 16 x 16843008 parts its 10-byte dimensions gave), and its kin.
  SECTION("a function handle whose dimensions are not whole miINT32 values") {
    std::string bytes = plain;
    SetWord(&bytes, 144, 16);  // function handle class
    SetWord(&bytes, 156, 10);
    SetWord(&bytes, 160, 0x01010000);
    WriteBytes(path, bytes);
    CHECK_THROWS_WITH(LoadOscillogram(path),
                      Contains("dimensions are 10 bytes, not whole miINT32 values (byte 152)"));
  }
  SECTION("a function handle whose part is not a variable") {
    std::string bytes = plain;
    SetWord(&bytes, 144, 16);
    SetWord(&bytes, 160, 1);  // 1 x 1: one part, where the time's values are
    WriteBytes(path, bytes);
    CHECK_THROWS_WITH(LoadOscillogram(path),
                      Contains("function handle part must be a miMATRIX element"));
  }
  SECTION("a compressed function handle with one-word dimensions") {
    std::string variable = inflated;
    SetWord(&variable, 16, 16);
    SetWord(&variable, 24, 4u << 16 | 5);  // a small miINT32 element of 4 bytes
    SetWord(&variable, 28, 0x7FFFFFF0);    // which libmatio takes for the dimensions' bytes
    WriteBytes(path, ReplaceFirst(zipped, variable));
    CHECK_THROWS_WITH(LoadOscillogram(path),
                      Contains("dimensions must be two or more miINT32") &&
                          Contains("of the variable compressed at byte 128"));
  }
  SECTION("an object whose name declares more than the file holds") {
    std::string bytes = plain;
    SetWord(&bytes, 144, 17);  // object (opaque) class: no dimensions, its name follows
    SetWord(&bytes, 152, 1);   // miINT8 of 8 bytes, in which libmatio reads a name tag
    SetWord(&bytes, 160, 1);
    SetWord(&bytes, 164, 0x7FFFFFF0);
    WriteBytes(path, bytes);
    CHECK_THROWS_WITH(
        LoadOscillogram(path),
        Contains("an object's name declares 2147483632 bytes") && Contains("(byte 160)"));
  }
  SECTION("a compressed variable that declares more than its stream can hold") {
    std::string variable = inflated;
    SetWord(&variable, 4, 0xF0000000);
    WriteBytes(path, ReplaceFirst(zipped, variable));
    CHECK_THROWS_WITH(LoadOscillogram(path), Contains("compressed bytes can hold"));
  }
  SECTION("a compressed stream cut short") {
    std::string bytes = zipped;
    const std::uint32_t size = Word(zipped, 132);
    bytes.erase(136 + size / 2, size - size / 2);
    SetWord(&bytes, 132, size / 2);
    WriteBytes(path, bytes);
    CHECK_THROWS_WITH(LoadOscillogram(path), Contains("zlib stream ends or breaks after"));
  }
  SECTION("a header of neither v5 nor v7.3") {
    std::string bytes = plain;
    bytes[124] = 0x07;
    WriteBytes(path, bytes);
    CHECK_THROWS_WITH(LoadOscillogram(path), Contains("not a MAT v5 or v7.3 file: version"));
  }
  SECTION("a file shorter than its header") {
    WriteBytes(path, plain.substr(0, 100));
    CHECK_THROWS_WITH(LoadOscillogram(path), Contains("shorter than the 128-byte MAT header"));
  }
}

TEST_CASE("identify reads a .mat record with logger time from the command line") {
  ScratchDir dir;
  Oscillogram csv = Mill5Record(0.01, 12, 0.0, 3);
  for (double& t : csv.time_s) t += 7.25;
  WriteTopLevel(dir / "rec.mat", MAT_FT_MAT73, csv);
  // The bundled config has no window: the fit takes the record's own span, 7.25 … 7.65 s.
  const auto run = millkit::testing::RunMillkit(
      "identify '" + millkit::testing::SourcePath("datasets/scenes/mill5_bite.toml") +
      "' --data '" + (dir / "rec.mat").string() + "' --config '" +
      millkit::testing::SourcePath("datasets/records/mill5_two_spindles.fit.toml") + "' --out '" +
      (dir / "fit.json").string() + "' --quiet");
  INFO(run.stderr_text);
  CHECK(run.exit_code == 0);
  CHECK_THAT(run.stdout_text, Contains("rec.mat") && Contains("time origin: record time 7.25 s"));
}

}  // namespace millkit::identify
