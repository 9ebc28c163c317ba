// The program itself: --version, and a subcommand is required.
#include <catch2/catch.hpp>

#include "support/run_cli.h"

using Catch::Matchers::Contains;
using millkit::testing::RunMillkit;

TEST_CASE("millkit --version prints the version and exits 0") {
  const auto run = RunMillkit("--version");
  CHECK(run.exit_code == 0);
  CHECK_THAT(run.stdout_text, Contains("millkit ") && Contains("."));
}

TEST_CASE("millkit without a subcommand exits 2 naming the subcommands") {
  const auto run = RunMillkit("");
  CHECK(run.exit_code == 2);
  CHECK_THAT(run.stderr_text + run.stdout_text, Contains("subcommand"));
}
