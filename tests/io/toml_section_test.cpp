#include "io/toml_section.h"

#include <catch2/catch.hpp>
#include <cmath>

using Catch::Matchers::Contains;
using millkit::TomlSection;

namespace {
toml::table Parse(const char* text) { return toml::parse(text); }
}  // namespace

TEST_CASE("An unknown key is named with the allowed ones", "[toml]") {
  const auto doc = Parse("stiffnes = 3.0\n");
  const TomlSection section(doc, "s.toml", "[[link]] #1");
  REQUIRE_THROWS_WITH(section.RequireOnlyKeys({"stiffness", "damping"}),
                      Contains("s.toml: [[link]] #1 key 'stiffnes'") && Contains("unknown key") &&
                          Contains("stiffness, damping"));
}

TEST_CASE("A missing required number names the key", "[toml]") {
  const auto doc = Parse("a = 1\n");
  const TomlSection section(doc, "s.toml", "[scene]");
  REQUIRE_THROWS_WITH(section.RequiredNumber("duration"),
                      Contains("key 'duration'") && Contains("is required"));
}

TEST_CASE("A string where a number belongs is rejected", "[toml]") {
  const auto doc = Parse("a = \"x\"\n");
  const TomlSection section(doc, "s.toml", "");
  REQUIRE_THROWS_WITH(section.RequiredNumber("a"), Contains("must be a number"));
}

TEST_CASE("Integers are read as numbers and range rules name the value", "[toml]") {
  const auto doc = Parse("a = 3\nb = -2.5\n");
  const TomlSection section(doc, "s.toml", "");
  CHECK(section.RequiredNumber("a") == 3.0);
  REQUIRE_THROWS_WITH(section.Positive("b", section.RequiredNumber("b")),
                      Contains("must be > 0 (got -2.5)"));
  REQUIRE_THROWS_WITH(section.InRange("b", -2.5, -1.0, 1.0), Contains("[-1, 1]"));
}

TEST_CASE("A value with its standard error keeps the digits the error supports", "[format]") {
  using millkit::ValueWithError;
  // The error to two significant digits, the value rounded to the same place.
  CHECK(ValueWithError(12345.678, 49.3) == "12346 \u00b1 49");
  CHECK(ValueWithError(0.0235123, 0.000213) == "0.02351 \u00b1 0.00021");
  CHECK(ValueWithError(6180.4, 412.0) == "6180 \u00b1 410");
  CHECK(ValueWithError(1.1512345e7, 3.4e4) == "(1.1512 \u00b1 0.0034)e7");
  CHECK(ValueWithError(-0.0001, 0.5) == "0.00 \u00b1 0.50");  // no "-0"
  // No error to go by: four significant digits.
  CHECK(ValueWithError(1.1512345e7, std::nan("")) == "1.151e+07");
  CHECK(ValueWithError(0.0235123, 0.0) == "0.02351");
}
