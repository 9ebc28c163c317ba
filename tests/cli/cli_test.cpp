// The program itself: --version, a subcommand is required, the --threads default.
#include <sched.h>

#include <algorithm>
#include <catch2/catch.hpp>
#include <cstdlib>
#include <string>

#include "cli/default_threads.h"
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

TEST_CASE(
    "the default of --threads is the cores the process may use shared among the node's ranks") {
  cpu_set_t mask;
  CPU_ZERO(&mask);
  REQUIRE(::sched_getaffinity(0, sizeof(mask), &mask) == 0);
  const int cores = CPU_COUNT(&mask);
  ::unsetenv("OMPI_COMM_WORLD_LOCAL_SIZE");
  ::unsetenv("MPI_LOCALNRANKS");
  CHECK(millkit::cli::DefaultThreads() == std::min(cores, 256));
  // Two ranks of a job on this node share its cores; more ranks than cores get one each.
  ::setenv("OMPI_COMM_WORLD_LOCAL_SIZE", "2", 1);
  CHECK(millkit::cli::DefaultThreads() == std::clamp(cores / 2, 1, 256));
  ::unsetenv("OMPI_COMM_WORLD_LOCAL_SIZE");
  ::setenv("MPI_LOCALNRANKS", "100000", 1);
  CHECK(millkit::cli::DefaultThreads() == 1);
  ::unsetenv("MPI_LOCALNRANKS");
  // Every command that runs work in parallel says its default in --help.
  const std::string shown = "--threads INT=" + std::to_string(std::min(cores, 256)) + " ";
  for (const std::string command : {"identify --help", "sweep --help", "coupling --help"}) {
    const auto help = RunMillkit(command);
    INFO(command << "\n" << help.stdout_text);
    CHECK(help.exit_code == 0);
    CHECK_THAT(help.stdout_text, Contains(shown));
  }
}
