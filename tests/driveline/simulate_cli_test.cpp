// `millkit simulate` end to end: output format, exit codes, no partial files.
#include <catch2/catch.hpp>

#include "support/run_cli.h"

using namespace millkit::testing;
using Catch::Matchers::Contains;
using Catch::Matchers::StartsWith;

TEST_CASE("simulate writes the CSV columns of the issue and prints the Kd table", "[cli]") {
  ScratchDir dir;
  const auto out = dir / "result.csv";
  const auto run = RunMillkit("simulate '" + SourcePath("datasets/scenes/two_mass_step.toml") +
                              "' --out '" + out.string() + "'");
  REQUIRE(run.exit_code == 0);
  CHECK_THAT(ReadText(out), StartsWith("time,shaft,speed.motor,speed.roll,twist.shaft\n"));
  CHECK_THAT(run.stdout_text, Contains("shaft") && Contains("2.000"));
  CHECK_THAT(run.stderr_text, Contains("exact: success"));
}

TEST_CASE("simulate with the CVODE solver gives the same table", "[cli]") {
  ScratchDir dir;
  const auto run = RunMillkit("simulate '" + SourcePath("datasets/scenes/two_mass_step.toml") +
                              "' --out '" + (dir / "r.csv").string() + "' --solver cvode --rtol 1e-10");
  REQUIRE(run.exit_code == 0);
  CHECK_THAT(run.stdout_text, Contains("2.000"));
  CHECK_THAT(run.stderr_text, Contains("cvode: success"));
}

TEST_CASE("simulate on a bad scene exits 2 naming the key and leaves no file", "[cli][bad_input]") {
  ScratchDir dir;
  WriteText(dir / "bad.toml", "[scene]\nduration = 0.1\nsample_rate = 100\n[[mass]]\n"
                              "name = \"a\"\ninertia = -1\n");
  const auto run = RunMillkit("simulate '" + (dir / "bad.toml").string() + "' --out '" +
                              (dir / "out.csv").string() + "'");
  CHECK(run.exit_code == 2);
  CHECK_THAT(run.stderr_text, Contains("bad.toml") && Contains("key 'inertia'"));
  CHECK(dir.EntryCount() == 1);  // only bad.toml
}

TEST_CASE("simulate rejects an unknown solver and a bad tolerance with exit 2", "[cli][bad_input]") {
  ScratchDir dir;
  const std::string scene = "'" + SourcePath("datasets/scenes/two_mass_step.toml") + "'";
  const std::string out = " --out '" + (dir / "r.csv").string() + "'";
  auto run = RunMillkit("simulate " + scene + out + " --solver euler");
  CHECK(run.exit_code == 2);
  CHECK_THAT(run.stderr_text, Contains("--solver"));
  run = RunMillkit("simulate " + scene + out + " --rtol 5");
  CHECK(run.exit_code == 2);
  CHECK_THAT(run.stderr_text, Contains("--rtol"));
  run = RunMillkit("simulate " + scene + out + " --rtol abc");
  CHECK(run.exit_code == 2);
  CHECK(dir.EntryCount() == 0);
}

TEST_CASE("simulate into a missing directory exits 2", "[cli][bad_input]") {
  const auto run = RunMillkit("simulate '" + SourcePath("datasets/scenes/two_mass_step.toml") +
                              "' --out /no/such/dir/r.csv");
  CHECK(run.exit_code == 2);
  CHECK_THAT(run.stderr_text, Contains("/no/such/dir") && Contains("does not exist"));
}
