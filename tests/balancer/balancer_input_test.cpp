// Reading and validating a balancer description (balancer_input.h): the seed dataset, the round
// trip through TOML, and every kind of bad input named by file, table and key.
#include "millkit/balancer/balancer_input.h"

#include <catch2/catch.hpp>
#include <string>

#include "balancer/balancer_toml.h"
#include "io/toml_section.h"
#include "millkit/io/input_error.h"
#include "support/run_cli.h"

namespace bal = millkit::balancer;
using Catch::Matchers::Contains;
using millkit::InputError;
using millkit::testing::SourcePath;

namespace {

const char* const kSeedDataset = "datasets/balancer/seed_002_stand950.toml";

// The seed case as TOML text with `from` replaced by `to` (one edit per bad-input test).
toml::table SeedDocumentWith(const std::string& from, const std::string& to) {
  std::string text = millkit::testing::ReadText(SourcePath(kSeedDataset));
  const auto at = text.find(from);
  REQUIRE(at != std::string::npos);
  text.replace(at, from.size(), to);
  return toml::parse(text);
}

bal::BalancerInput ReadEdited(const std::string& from, const std::string& to) {
  return bal::ReadBalancerInput(SeedDocumentWith(from, to), "b.toml");
}

}  // namespace

TEST_CASE("The seed dataset describes the same device as the built-in seed case", "[input]") {
  const auto from_file =
      bal::ReadBalancerInput(millkit::LoadTomlFile(SourcePath(kSeedDataset)), kSeedDataset);
  CHECK(bal::ToToml(from_file) == bal::ToToml(bal::SeedCase()));
}

TEST_CASE("The public file reader reads the seed dataset as the built-in seed case", "[input]") {
  const auto from_file = bal::ReadBalancerInputFile(SourcePath(kSeedDataset));
  CHECK(bal::ToToml(from_file) == bal::ToToml(bal::SeedCase()));
}

TEST_CASE("The public file reader names a file it cannot read", "[input]") {
  REQUIRE_THROWS_WITH(bal::ReadBalancerInputFile("no/such/balancer.toml"),
                      Contains("no/such/balancer.toml"));
}

TEST_CASE("An input survives the round trip through TOML", "[input]") {
  bal::BalancerInput input = bal::SeedCase();
  input.support.alpha_deg = 25.0;
  input.contact.count = 4;
  input.balance.balancing_force_N = 120000.0;
  const auto back = bal::ReadBalancerInput(bal::ToToml(input), "round trip");
  CHECK(bal::ToToml(back) == bal::ToToml(input));
  CHECK(back.contact.count == 4);
}

TEST_CASE("The seed case breaks no input rule", "[input]") {
  CHECK_FALSE(bal::FindInputViolation(bal::SeedCase()).has_value());
  CHECK_NOTHROW(bal::Validate(bal::SeedCase()));
}

TEST_CASE("A negative load is refused with its key, line and value", "[input]") {
  REQUIRE_THROWS_WITH(
      ReadEdited("support_load_N = 111530.0", "support_load_N = -5.0"),
      Contains("b.toml: [load] key 'support_load_N' (line 7)") && Contains("must be > 0 (got -5)"));
}

TEST_CASE("A support angle that makes cos(alpha + 2 beta) non-positive names alpha", "[input]") {
  // 60 + 2 · 17.5 = 95° > 90°.
  REQUIRE_THROWS_WITH(ReadEdited("alpha_deg = 30.0", "alpha_deg = 60.0"),
                      Contains("[support] key 'alpha_deg'") && Contains("cos(alpha + 2*beta) > 0"));
}

TEST_CASE("The angle rule uses beta as rounded, so 55 degrees is already too steep", "[input]") {
  // 55 + 2 · 17.5 = 90° exactly: cos = 0, P1 unbounded.
  REQUIRE_THROWS_WITH(ReadEdited("alpha_deg = 30.0", "alpha_deg = 55.0"),
                      Contains("key 'alpha_deg'") && Contains("sum 90"));
}

TEST_CASE("A missing key is named", "[input]") {
  REQUIRE_THROWS_WITH(ReadEdited("width_m = 0.060", ""),
                      Contains("b.toml: [contact] key 'width_m'") && Contains("is required"));
}

TEST_CASE("A missing table is named", "[input]") {
  toml::table document = bal::ToToml(bal::SeedCase());
  document.erase("axle");
  REQUIRE_THROWS_WITH(bal::ReadBalancerInput(document, "b.toml"),
                      Contains("key 'axle'") && Contains("is required"));
}

TEST_CASE("An unknown key is named with the allowed ones", "[input]") {
  REQUIRE_THROWS_WITH(ReadEdited("s3 = 1.5", "s3 = 1.5\ns4 = 1.0"), Contains("[cross] key 's4'") &&
                                                                        Contains("unknown key") &&
                                                                        Contains("s1, s2, s3"));
}

TEST_CASE("An unknown table is named", "[input]") {
  toml::table document = bal::ToToml(bal::SeedCase());
  document.insert("hydraulics", toml::table{});
  REQUIRE_THROWS_WITH(bal::ReadBalancerInput(document, "b.toml"),
                      Contains("key 'hydraulics'") && Contains("unknown table"));
}

TEST_CASE("A value that is not a number is named", "[input]") {
  REQUIRE_THROWS_WITH(ReadEdited("pin_arm_m = 0.156", "pin_arm_m = \"0.156\""),
                      Contains("[cross] key 'pin_arm_m'") && Contains("must be a number"));
}

TEST_CASE("A fractional roller count is refused", "[input]") {
  REQUIRE_THROWS_WITH(ReadEdited("count = 8", "count = 7.5"),
                      Contains("[contact] key 'count'") && Contains("must be an integer"));
}

TEST_CASE("A safety factor below one is refused with its key", "[input]") {
  REQUIRE_THROWS_WITH(ReadEdited("s1 = 1.5", "s1 = 0.8"),
                      Contains("[cross] key 's1'") && Contains("must be >= 1 (got 0.8)"));
}

TEST_CASE("An open limit below the closed limit is refused", "[input]") {
  REQUIRE_THROWS_WITH(
      ReadEdited("open_beyond_percent = 5.0", "open_beyond_percent = 2.0"),
      Contains("[balance] key 'open_beyond_percent'") && Contains("closed_within_percent = 3"));
}

TEST_CASE("Validate names the table and key for library callers", "[input]") {
  bal::BalancerInput input = bal::SeedCase();
  input.axle.support_span_m = 0.0;
  REQUIRE_THROWS_AS(bal::Validate(input), InputError);
  REQUIRE_THROWS_WITH(bal::Validate(input), Contains("[axle] key 'support_span_m'"));
}
