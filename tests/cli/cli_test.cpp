// The program itself: --version, a subcommand is required, the --threads default.
#include <sched.h>
#include <sys/stat.h>

#include <algorithm>
#include <catch2/catch.hpp>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

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

TEST_CASE("an input that cannot be a file is named with exit 2 and a pipe is read") {
  using millkit::testing::ScratchDir;
  using millkit::testing::Shell;
  using millkit::testing::SourcePath;
  namespace fs = std::filesystem;
  ScratchDir dir;
  fs::create_directory(dir / "folder");
  fs::create_symlink("b.toml", dir / "a.toml");
  fs::create_symlink("a.toml", dir / "b.toml");
  const std::string out = " --out '" + (dir / "out.csv").string() + "'";
  struct Case {
    std::string input, says;
  };
  for (const Case& c : {Case{(dir / "folder").string(), "is a directory"},
                        Case{(dir / "a.toml").string(), "cannot be read"},
                        Case{(dir / "none.toml").string(), "file not found"}}) {
    // As a scene (TOML) and as a record (CSV).
    for (const std::string& command :
         std::vector<std::string>{"simulate '" + c.input + "'" + out,
                                  "identify '" + SourcePath("datasets/scenes/mill5_bite.toml") +
                                      "' --data '" + c.input + "'" + out}) {
      const auto run = RunMillkit(command);
      INFO(command << "\n" << run.stderr_text);
      CHECK(run.exit_code == 2);
      CHECK_THAT(run.stderr_text, Contains(c.input + ": " + c.says));
      CHECK_FALSE(fs::exists(dir / "out.csv"));
    }
  }
  // A scene through a pipe (a FIFO here; a shell's <(...) is one).
  REQUIRE(::mkfifo((dir / "scene.toml").c_str(), 0600) == 0);
  const int code =
      Shell(dir, "cat '" + SourcePath("datasets/scenes/two_mass_step.toml") + "' > '" +
                     (dir / "scene.toml").string() + "' & '" + MILLKIT_BINARY + "' simulate '" +
                     (dir / "scene.toml").string() + "'" + out + "; status=$?; wait; exit $status");
  INFO(millkit::testing::ReadText(dir / "stderr"));
  CHECK(code == 0);
  CHECK(fs::file_size(dir / "out.csv") > 0);
}
