// COMTRADE records (issue 13, item 2): the tests write their own .cfg/.dat pairs.
#include "millkit/identify/comtrade.h"

#include <catch2/catch.hpp>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>

#include "fit_fixture.h"
#include "millkit/io/input_error.h"
#include "support/run_cli.h"

namespace millkit::identify {
namespace {

using Catch::Matchers::Contains;
using millkit::identify::testing::CheckSameFit;
using millkit::testing::ScratchDir;
using millkit::testing::WriteText;
using testing::Mill5Config;
using testing::Mill5Record;
using testing::Mill5Scene;

std::string Cfg(const Oscillogram& record, const std::string& type, double a, double b,
                bool with_rate) {
  std::string cfg = "MILL5,BENCH,1999\n";
  const size_t m = record.channels.size();
  cfg += std::to_string(m + 1) + "," + std::to_string(m) + "A,1D\n";
  char line[256];
  for (size_t c = 0; c < m; ++c) {
    std::snprintf(line, sizeof(line), "%zu,%s,,,Nm,%.17g,%.17g,0,-32767,32767,1,1,P\n", c + 1,
                  record.channels[c].c_str(), a, b);
    cfg += line;
  }
  cfg += "1,breaker,,,0\n50\n";
  const double rate = 1.0 / (record.time_s[1] - record.time_s[0]);
  cfg += "1\n";
  cfg += with_rate ? std::to_string(rate) : std::string("0");
  cfg += ",";
  cfg += std::to_string(record.time_s.size());
  cfg += "\n";
  cfg += "01/01/2026,00:00:00.000000\n01/01/2026,00:00:00.050000\n";
  cfg += type;
  cfg += "\n1\n";
  return cfg;
}

void WriteBinary(const std::filesystem::path& path, const Oscillogram& record,
                 const std::string& type, double a, double b) {
  std::ofstream out(path, std::ios::binary);
  const auto put32 = [&](std::uint32_t v) {
    for (int k = 0; k < 4; ++k) out.put(static_cast<char>((v >> (8 * k)) & 0xff));
  };
  for (size_t k = 0; k < record.time_s.size(); ++k) {
    put32(static_cast<std::uint32_t>(k + 1));
    put32(static_cast<std::uint32_t>(std::llround(record.time_s[k] * 1e6)));
    for (const auto& column : record.values) {
      const double x = (column[k] - b) / a;
      if (type == "BINARY") {
        const auto v = static_cast<std::uint16_t>(static_cast<std::int16_t>(std::lround(x)));
        out.put(static_cast<char>(v & 0xff));
        out.put(static_cast<char>(v >> 8));
      } else if (type == "BINARY32") {
        put32(static_cast<std::uint32_t>(static_cast<std::int32_t>(std::llround(x))));
      } else {
        const float f = static_cast<float>(x);
        std::uint32_t bits = 0;
        std::memcpy(&bits, &f, sizeof(bits));
        put32(bits);
      }
    }
    out.put(0);
    out.put(0);  // one word of digital channels
  }
}

}  // namespace

TEST_CASE("COMTRADE ASCII reads the same record as its CSV and fits to the same values") {
  ScratchDir dir;
  const Oscillogram csv = Mill5Record(0.01, 12, 0.0, 3);
  WriteText(dir / "rec.cfg", Cfg(csv, "ASCII", 1.0, 0.0, true));
  std::string dat;
  char line[512];
  for (size_t k = 0; k < csv.time_s.size(); ++k) {
    std::snprintf(line, sizeof(line), "%zu,%lld", k + 1, std::llround(csv.time_s[k] * 1e6));
    dat += line;
    for (const auto& column : csv.values) {
      std::snprintf(line, sizeof(line), ",%.17g", column[k]);
      dat += line;
    }
    dat += ",0\n";
  }
  WriteText(dir / "rec.dat", dat);
  const Oscillogram record = LoadOscillogram(dir / "rec.cfg");
  REQUIRE(record.channels == csv.channels);
  REQUIRE(record.time_s.size() == csv.time_s.size());
  // Times k/samp from the .cfg's rate are the CSV's k/2000 exactly; values printed with 17 digits.
  CHECK(record.time_s == csv.time_s);
  CHECK(record.values == csv.values);
  CHECK(record.units == std::vector<std::string>(csv.channels.size(), "Nm"));  // the .cfg's uu
  auto scene = Mill5Scene();
  const FitConfig config = Mill5Config(csv, &scene);
  CheckSameFit(Fit(scene, csv, config, FitOptions{}), Fit(scene, record, config, FitOptions{}));
}

TEST_CASE("COMTRADE binary files read within their resolution") {
  ScratchDir dir;
  const Oscillogram csv = Mill5Record(0.01, 12, 0.0, 3);
  double peak = 0.0;
  for (const auto& column : csv.values) {
    for (const double v : column) peak = std::max(peak, std::abs(v));
  }
  for (const std::string type : {"BINARY", "BINARY32", "FLOAT32"}) {
    const double a = type == "BINARY" ? peak / 30000.0 : peak / 1e9;
    const double b = 100.0;
    WriteText(dir / "bin.cfg", Cfg(csv, type, a, b, false));
    WriteBinary(dir / "bin.dat", csv, type, a, b);
    const Oscillogram record = LoadOscillogram(dir / "bin.cfg");
    INFO(type);
    REQUIRE(record.values.size() == csv.values.size());
    REQUIRE(record.time_s.size() == csv.time_s.size());
    double worst = 0.0;
    for (size_t c = 0; c < csv.values.size(); ++c) {
      for (size_t k = 0; k < csv.time_s.size(); ++k) {
        worst = std::max(worst, std::abs(record.values[c][k] - csv.values[c][k]));
      }
    }
    // Rounding to the integer step a, or float32's 24 bits.
    const double resolution = type == "FLOAT32" ? peak * 1e-7 : 0.5 * a * (1.0 + 1e-9);
    CHECK(worst <= resolution);
    CHECK(record.time_s.back() == Approx(csv.time_s.back()).margin(1e-6));
  }
}

TEST_CASE("COMTRADE files that are wrong are errors naming the file and the rule") {
  ScratchDir dir;
  const Oscillogram csv = Mill5Record(0.0, 0, 0.0, 1);
  SECTION("an unknown file type") {
    WriteText(dir / "x.cfg", Cfg(csv, "HEX", 1.0, 0.0, true));
    WriteText(dir / "x.dat", "");
    CHECK_THROWS_WITH(LoadOscillogram(dir / "x.cfg"), Contains("x.cfg") && Contains("'HEX'"));
  }
  SECTION("a truncated binary file") {
    WriteText(dir / "t.cfg", Cfg(csv, "BINARY32", 1.0, 0.0, true));
    WriteBinary(dir / "t.dat", csv, "BINARY32", 1.0, 0.0);
    std::filesystem::resize_file(dir / "t.dat", std::filesystem::file_size(dir / "t.dat") - 3);
    CHECK_THROWS_WITH(LoadOscillogram(dir / "t.cfg"), Contains("t.dat") && Contains("truncated"));
  }
  SECTION("channel counts that do not add up") {
    std::string cfg = Cfg(csv, "ASCII", 1.0, 0.0, true);
    cfg[cfg.find('\n') + 1] = '9';
    WriteText(dir / "c.cfg", cfg);
    WriteText(dir / "c.dat", "");
    CHECK_THROWS_WITH(LoadOscillogram(dir / "c.cfg"), Contains("c.cfg: line 2"));
  }
  SECTION("a missing .dat") {
    WriteText(dir / "m.cfg", Cfg(csv, "ASCII", 1.0, 0.0, true));
    CHECK_THROWS_WITH(LoadOscillogram(dir / "m.cfg"), Contains("m.dat"));
  }
}

}  // namespace millkit::identify
