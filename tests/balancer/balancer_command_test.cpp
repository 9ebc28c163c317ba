// `millkit balancer` end to end: exit codes (SPEC.md §8), the table, the JSON result and no
// partial output on bad input.
#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>
#include <string>

#include "printed_value.h"
#include "support/run_cli.h"

using Catch::Matchers::Contains;
using millkit::balancer::testing::RoundsTo;
using millkit::testing::ReadText;
using millkit::testing::RunMillkit;
using millkit::testing::ScratchDir;
using millkit::testing::SourcePath;
using millkit::testing::WriteText;

namespace {

constexpr int kExitOk = 0;
constexpr int kExitBadInput = 2;

std::string Quoted(const std::filesystem::path& path) {
  std::string quoted = "'";
  quoted.append(path.string()).append("'");
  return quoted;
}

// Runs `millkit balancer <arguments> --out <dir>/result.json` and expects bad input: exit 2, the
// message naming `named`, and nothing left in the directory.
void ExpectBadInput(const std::string& arguments, const std::string& named) {
  ScratchDir dir;
  const auto result = RunMillkit("balancer " + arguments + " --out " + Quoted(dir / "result.json"));
  CHECK(result.exit_code == kExitBadInput);
  CHECK_THAT(result.stderr_text, Contains(named));
  CHECK(dir.EntryCount() == 0);
}

}  // namespace

TEST_CASE("The balancer with no config prints the seed case and writes its JSON", "[cli]") {
  ScratchDir dir;
  const auto result = RunMillkit("balancer --out " + Quoted(dir / "result.json"));
  REQUIRE(result.exit_code == kExitOk);
  CHECK_THAT(result.stdout_text, Contains("65975.6") && Contains("6644.7") && Contains("7074.66") &&
                                     Contains("gap_position"));
  const auto json = nlohmann::json::parse(ReadText(dir / "result.json"));
  // SPEC.md §7: P1 = 65 975.6 N, M(329 mm) = 6812 N·m.
  CHECK_THAT(json["support"]["P1_N"].get<double>(), RoundsTo(65975.6, 1));
  CHECK_THAT(json["roller"]["M_x2_Nm"].get<double>(), RoundsTo(6812.0, 0));
  CHECK(json["idle_gaps"]["state"] == "closed");
  CHECK(json["idle_gaps"]["gap_position"].get<double>() == 1.0);
  CHECK(json["all_checks_pass"] == true);
  CHECK(dir.EntryCount() == 1);
}

TEST_CASE("The seed dataset gives the same JSON as the built-in seed case", "[cli]") {
  ScratchDir dir;
  REQUIRE(RunMillkit("balancer --out " + Quoted(dir / "default.json")).exit_code == kExitOk);
  REQUIRE(RunMillkit("balancer --config " +
                     Quoted(SourcePath("datasets/balancer/seed_002_stand950.toml")) + " --out " +
                     Quoted(dir / "dataset.json"))
              .exit_code == kExitOk);
  CHECK(nlohmann::json::parse(ReadText(dir / "default.json")) ==
        nlohmann::json::parse(ReadText(dir / "dataset.json")));
}

TEST_CASE("A balancing force 8 percent high opens the gaps and writes gap_position -1", "[cli]") {
  ScratchDir dir;
  // 111 530 N · 1.08 = 120 452.4 N.
  const auto result =
      RunMillkit("balancer --balancing-force 120452.4 --out " + Quoted(dir / "result.json"));
  REQUIRE(result.exit_code == kExitOk);
  CHECK_THAT(result.stdout_text, Contains("over-balance") && Contains("open"));
  const auto json = nlohmann::json::parse(ReadText(dir / "result.json"));
  CHECK_THAT(json["idle_gaps"]["imbalance_percent"].get<double>(), RoundsTo(8.0, 6));
  CHECK(json["idle_gaps"]["state"] == "open");
  CHECK(json["idle_gaps"]["gaps_open_at_idle"] == true);
  CHECK(json["idle_gaps"]["gap_position"].get<double>() == -1.0);
}

TEST_CASE("Flags override single inputs of the seed case", "[cli]") {
  ScratchDir dir;
  // S1 = S2 = S3 = 1 gives [σ] = σв = 1370 MPa; 4 % under-balance lies mid-band.
  const auto result = RunMillkit(
      "balancer --set cross.s1=1 --set cross.s2=1 --set cross.s3=1 "
      "--required-force 100000 --balancing-force 96000 --out " +
      Quoted(dir / "result.json"));
  REQUIRE(result.exit_code == kExitOk);
  const auto json = nlohmann::json::parse(ReadText(dir / "result.json"));
  CHECK(json["cross"]["safety_factor"].get<double>() == 1.0);
  CHECK(json["cross"]["allowable_stress_Pa"].get<double>() == 1370.0e6);
  CHECK(json["idle_gaps"]["state"] == "intermittent");
  CHECK_THAT(json["idle_gaps"]["gap_position"].get<double>(),
             Catch::Matchers::WithinAbs(0.0, 1e-9));
}

TEST_CASE("The balancer runs without --out and writes nothing", "[cli]") {
  const auto result = RunMillkit("balancer");
  CHECK(result.exit_code == kExitOk);
  CHECK_THAT(result.stdout_text, Contains("Roller support"));
}

TEST_CASE("A negative load on the command line exits 2 naming the key", "[cli]") {
  ExpectBadInput("--set load.support_load_N=-5", "support_load_N");
}

TEST_CASE("A support angle with cos(alpha + 2 beta) <= 0 exits 2 naming alpha", "[cli]") {
  ExpectBadInput("--set support.alpha_deg=60", "alpha_deg");
}

TEST_CASE("A negative balancing force exits 2 naming the key", "[cli]") {
  ExpectBadInput("--balancing-force -1000", "balancing_force_N");
}

TEST_CASE("A non-numeric flag value exits 2", "[cli]") {
  ExpectBadInput("--set cross.s1=abc", "cross.s1");
  ExpectBadInput("--balancing-force lots", "--balancing-force");
}

TEST_CASE("An unknown key on the command line exits 2 naming it", "[cli]") {
  ExpectBadInput("--set cross.s4=1", "cross.s4");
}

TEST_CASE("A config with a missing key exits 2 naming it and leaves no output", "[cli]") {
  ScratchDir input_dir;
  std::string text = ReadText(SourcePath("datasets/balancer/seed_002_stand950.toml"));
  const std::string line = "half_loaded_length_m = 0.245";
  text.erase(text.find(line), line.size());
  WriteText(input_dir / "b.toml", text);
  ExpectBadInput("--config " + Quoted(input_dir / "b.toml"), "half_loaded_length_m");
}

TEST_CASE("A config with a non-numeric value exits 2 naming the key", "[cli]") {
  ScratchDir input_dir;
  std::string text = ReadText(SourcePath("datasets/balancer/seed_002_stand950.toml"));
  const std::string line = "duty_factor = 1.6";
  text.replace(text.find(line), line.size(), "duty_factor = \"high\"");
  WriteText(input_dir / "b.toml", text);
  ExpectBadInput("--config " + Quoted(input_dir / "b.toml"), "duty_factor");
}

TEST_CASE("A missing config file exits 2 naming the file", "[cli]") {
  ExpectBadInput("--config /nonexistent/b.toml", "/nonexistent/b.toml");
}

TEST_CASE("An output in a missing directory exits 2", "[cli]") {
  const auto result = RunMillkit("balancer --out /nonexistent/dir/result.json");
  CHECK(result.exit_code == kExitBadInput);
}
