#include "millkit/io/atomic_file.h"

#include <catch2/catch.hpp>

#include "support/run_cli.h"

using millkit::AtomicFile;
using millkit::testing::ReadText;
using millkit::testing::ScratchDir;

TEST_CASE("A committed atomic file holds its content and no temporary remains", "[atomic]") {
  ScratchDir dir;
  {
    AtomicFile file(dir / "out.csv");
    file.stream() << "a,b\n";
    file.Commit();
  }
  CHECK(ReadText(dir / "out.csv") == "a,b\n");
  CHECK(dir.EntryCount() == 1);
}

TEST_CASE("An atomic file destroyed without commit leaves nothing behind", "[atomic]") {
  ScratchDir dir;
  {
    AtomicFile file(dir / "out.csv");
    file.stream() << "partial";
  }
  CHECK(dir.EntryCount() == 0);
}

TEST_CASE("An atomic file in a missing directory is a clear input error", "[atomic]") {
  ScratchDir dir;
  REQUIRE_THROWS_WITH(AtomicFile(dir / "no/such/dir/out.csv"),
                      Catch::Matchers::Contains("cannot open for writing"));
}
