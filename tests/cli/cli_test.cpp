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

TEST_CASE("an option the library refuses is named by its flag, not by the library's field") {
  const millkit::testing::ScratchDir dir;
  const std::string scene =
      "'" + millkit::testing::SourcePath("datasets/scenes/two_mass_step.toml") + "'";
  struct Case {
    std::string arguments;
    std::string flag;
  };
  const Case cases[] = {
      {"simulate " + scene + " --kd-only --solver cvode --rtol 1", "option --rtol: must lie in"},
      {"leveller forces --yield-mpa 550 --width-mm 1900 --thickness-mm 6 --shape-factor 0.5 "
       "--out '" +
           (dir / "forces.json").string() + "'",
       "option --shape-factor: must be >= 1"},
  };
  for (const auto& c : cases) {
    const auto run = RunMillkit(c.arguments);
    INFO(c.arguments << "\n" << run.stderr_text);
    CHECK(run.exit_code == 2);
    CHECK_THAT(run.stderr_text, Contains(c.flag));
    CHECK_THAT(run.stderr_text, !Contains("Options::"));
  }
}
