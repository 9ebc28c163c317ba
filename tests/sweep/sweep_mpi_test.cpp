// `millkit sweep` under mpirun: the same rows as a serial run (when built with MPI), and a clear
// refusal when started by mpirun but built without it.
#include <unistd.h>

#include <catch2/catch.hpp>
#include <cstdlib>

#include "support/run_cli.h"

using namespace millkit::testing;
using Catch::Matchers::Contains;

namespace {

const std::string kConfig =
    "[sweep]\nmethod = \"lhs\"\nsamples = 15\nseed = 5\n"
    "[[parameter]]\nname = \"upper_spindle.damping\"\nlower = 1000\nupper = 9000\n"
    "[[parameter]]\nname = \"lower_spindle.backlash\"\nlower = 0\nupper = 0.04\n"
    "[[parameter]]\nname = \"upper_spindle.stiffness\"\nlower = 1e6\nupper = 1e12\n"
    "scale = \"log\"\n";  // the stiffest cases fail (sample rate): failed rows travel too

std::string SweepArguments(const ScratchDir& dir, const std::string& out) {
  return "sweep '" + SourcePath("datasets/scenes/mill5_bite.toml") + "' --config '" +
         (dir / "sweep.toml").string() + "' --out '" + (dir / out).string() + "' --quiet";
}

}  // namespace

#if MILLKIT_WITH_MPI
TEST_CASE("mpirun -np 2 writes the same rows as a serial run", "[sweep][cli][mpi]") {
  ScratchDir dir;
  WriteText(dir / "sweep.toml", kConfig);
  // The stiffest cases fail: exit 3 with every file written, on one rank and on two.
  REQUIRE(RunMillkit(SweepArguments(dir, "serial.csv")).exit_code == 3);
  const std::string root = geteuid() == 0 ? " --allow-run-as-root" : "";
  const int code = Shell(dir, "mpirun -np 2 --oversubscribe" + root + " '" MILLKIT_BINARY "' " +
                                  SweepArguments(dir, "mpi.csv") + " --threads 2");
  INFO(ReadText(dir / "stderr"));
  REQUIRE(code == 3);
  const std::string serial = ReadText(dir / "serial.csv");
  CHECK(ReadText(dir / "mpi.csv") == serial);
  CHECK_THAT(serial, Contains(",failed,") && Contains(",ok,"));
}

TEST_CASE("a sweep rank whose inputs fail stops every rank: no hang, no output",
          "[sweep][cli][mpi][bad_input]") {
  // Rank 1 (MPMD) gets a --threads it refuses; `timeout` turns a hang of rank 0 into exit 124.
  ScratchDir dir;
  WriteText(dir / "sweep.toml", kConfig);
  const std::string root = geteuid() == 0 ? " --allow-run-as-root" : "";
  const std::string program = " '" MILLKIT_BINARY "' " + SweepArguments(dir, "mpi.csv");
  const int code = Shell(dir, "timeout 120 mpirun --oversubscribe" + root + " -np 1" + program +
                                  " : -np 1" + program + " --threads 0");
  const std::string stderr_text = ReadText(dir / "stderr");
  INFO(stderr_text);
  CHECK(code != 0);
  CHECK(code != 124);
  CHECK_THAT(stderr_text, Contains("another MPI rank failed reading the sweep's inputs"));
  CHECK_FALSE(std::filesystem::exists(dir / "mpi.csv"));
}
#else
TEST_CASE("a millkit built without MPI refuses to run as several mpirun ranks",
          "[sweep][cli][mpi][bad_input]") {
  ScratchDir dir;
  WriteText(dir / "sweep.toml", kConfig);
  const int code =
      Shell(dir, "OMPI_COMM_WORLD_SIZE=2 '" MILLKIT_BINARY "' " + SweepArguments(dir, "out.csv"));
  CHECK(code == 2);
  CHECK_THAT(ReadText(dir / "stderr"), Contains("built without MPI"));
  CHECK_FALSE(std::filesystem::exists(dir / "out.csv"));
}
#endif
