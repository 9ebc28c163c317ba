// `millkit simulate` end to end: output format, exit codes, no partial files.
#include <catch2/catch.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "millkit/driveline/simulation.h"
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
  const auto run =
      RunMillkit("simulate '" + SourcePath("datasets/scenes/two_mass_step.toml") + "' --out '" +
                 (dir / "r.csv").string() + "' --solver cvode --rtol 1e-10");
  REQUIRE(run.exit_code == 0);
  CHECK_THAT(run.stdout_text, Contains("2.000"));
  CHECK_THAT(run.stderr_text, Contains("cvode: success"));
}

TEST_CASE("simulate on a bad scene exits 2 naming the key and leaves no file", "[cli][bad_input]") {
  ScratchDir dir;
  WriteText(dir / "bad.toml",
            "[scene]\nduration = 0.1\nsample_rate = 100\n[[mass]]\n"
            "name = \"a\"\ninertia = -1\n");
  const auto run = RunMillkit("simulate '" + (dir / "bad.toml").string() + "' --out '" +
                              (dir / "out.csv").string() + "'");
  CHECK(run.exit_code == 2);
  CHECK_THAT(run.stderr_text, Contains("bad.toml") && Contains("key 'inertia'"));
  CHECK(dir.EntryCount() == 1);  // only bad.toml
}

TEST_CASE("simulate rejects an unknown solver and a bad tolerance with exit 2",
          "[cli][bad_input]") {
  ScratchDir dir;
  const std::string scene = "'" + SourcePath("datasets/scenes/two_mass_step.toml") + "'";
  const std::string out = " --out '" + (dir / "r.csv").string() + "'";
  auto run = RunMillkit("simulate " + scene + out + " --solver euler");
  CHECK(run.exit_code == 2);
  CHECK_THAT(run.stderr_text, Contains("--solver"));
  CHECK_THAT(run.stderr_text, Contains("exact, cvode"));
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

namespace {
const std::string kTwoMass = "'" + SourcePath("datasets/scenes/two_mass_step.toml") + "'";

std::vector<std::string> Lines(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

std::vector<std::string> Cells(const std::string& line) {
  std::vector<std::string> cells;
  std::istringstream in(line);
  for (std::string cell; std::getline(in, cell, ',');) cells.push_back(cell);
  return cells;
}
}  // namespace

TEST_CASE("simulate --every N writes rows 0, N, 2N of the full CSV and the same Kd table",
          "[cli][stream]") {
  ScratchDir dir;
  const auto full =
      RunMillkit("simulate " + kTwoMass + " --out '" + (dir / "full.csv").string() + "'");
  const auto every = RunMillkit("simulate " + kTwoMass + " --every 7 --out '" +
                                (dir / "every.csv").string() + "'");
  REQUIRE(full.exit_code == 0);
  REQUIRE(every.exit_code == 0);
  CHECK(every.stdout_text == full.stdout_text);
  const auto all_rows = Lines(ReadText(dir / "full.csv"));
  const auto kept = Lines(ReadText(dir / "every.csv"));
  REQUIRE(all_rows.size() == 2002);  // header and 0 … 0.2 s at 10 kHz
  REQUIRE(kept.size() == 1 + (2001 - 1) / 7 + 1);
  CHECK(kept[0] == all_rows[0]);
  for (size_t r = 1; r < kept.size(); ++r) REQUIRE(kept[r] == all_rows[1 + 7 * (r - 1)]);
}

TEST_CASE("simulate --columns writes time and the named columns in that order", "[cli][stream]") {
  ScratchDir dir;
  REQUIRE(RunMillkit("simulate " + kTwoMass + " --out '" + (dir / "full.csv").string() + "'")
              .exit_code == 0);
  const auto run =
      RunMillkit("simulate " + kTwoMass + " --columns twist.shaft,speed.motor --out '" +
                 (dir / "some.csv").string() + "'");
  REQUIRE(run.exit_code == 0);
  const auto all_rows = Lines(ReadText(dir / "full.csv"));
  const auto some = Lines(ReadText(dir / "some.csv"));
  REQUIRE(some.size() == all_rows.size());
  CHECK(some[0] == "time,twist.shaft,speed.motor");
  for (size_t r = 1; r < some.size(); ++r) {
    const auto cells = Cells(all_rows[r]);  // time,shaft,speed.motor,speed.roll,twist.shaft
    REQUIRE(some[r] == cells[0] + "," + cells[4] + "," + cells[2]);
  }
}

TEST_CASE("simulate --columns with an unknown name exits 2 naming it and the allowed names",
          "[cli][bad_input][stream]") {
  ScratchDir dir;
  const auto run = RunMillkit("simulate " + kTwoMass + " --columns shaft,speed.rol --out '" +
                              (dir / "r.csv").string() + "'");
  CHECK(run.exit_code == 2);
  CHECK_THAT(run.stderr_text, Contains("--columns") && Contains("'speed.rol'") &&
                                  Contains("shaft, speed.motor, speed.roll, twist.shaft"));
  CHECK(dir.EntryCount() == 0);
}

TEST_CASE("simulate --kd-only prints the same table and writes no file", "[cli][stream]") {
  ScratchDir dir;
  const auto full =
      RunMillkit("simulate " + kTwoMass + " --out '" + (dir / "r.csv").string() + "'");
  std::filesystem::remove(dir / "r.csv");
  const auto kd = RunMillkit("simulate " + kTwoMass + " --kd-only");
  REQUIRE(full.exit_code == 0);
  REQUIRE(kd.exit_code == 0);
  CHECK(kd.stdout_text == full.stdout_text);
  CHECK(dir.EntryCount() == 0);
}

TEST_CASE("simulate --kd-only refuses --out, --every and --columns, and --every 0 is refused",
          "[cli][bad_input][stream]") {
  ScratchDir dir;
  const std::string out = " --out '" + (dir / "r.csv").string() + "'";
  auto run = RunMillkit("simulate " + kTwoMass + " --kd-only" + out);
  CHECK(run.exit_code == 2);
  CHECK_THAT(run.stderr_text, Contains("--out") && Contains("--kd-only"));
  run = RunMillkit("simulate " + kTwoMass + " --kd-only --every 3");
  CHECK(run.exit_code == 2);
  run = RunMillkit("simulate " + kTwoMass + " --kd-only --columns shaft");
  CHECK(run.exit_code == 2);
  run = RunMillkit("simulate " + kTwoMass);
  CHECK(run.exit_code == 2);
  CHECK_THAT(run.stderr_text, Contains("--out") && Contains("--kd-only"));
  run = RunMillkit("simulate " + kTwoMass + " --every 0" + out);
  CHECK(run.exit_code == 2);
  CHECK_THAT(run.stderr_text, Contains("--every") && Contains(">= 1"));
  CHECK(dir.EntryCount() == 0);
}

TEST_CASE(
    "simulate warns before a run whose CSV exceeds 1 GB, shows progress after 1 s, and an "
    "interrupt leaves no file",
    "[cli][stream]") {
  // mill5_bite over 1000 s: 5e6 rows of 14 numbers, about 1.4 GB. CVODE is slow enough that the
  // run is far from done when the interrupt comes, and the warning is printed before it starts.
  ScratchDir dir;
  std::string scene = ReadText(SourcePath("datasets/scenes/mill5_bite.toml"));
  const std::string duration = "duration = 0.5";
  REQUIRE(scene.find(duration) != std::string::npos);
  scene.replace(scene.find(duration), duration.size(), "duration = 1000");
  WriteText(dir / "long.toml", scene);
  const auto err = dir / "stderr";
  const std::string command = "timeout -s INT 2 '" + std::string(MILLKIT_BINARY) + "' simulate '" +
                              (dir / "long.toml").string() +
                              "' --solver cvode --no-check --rtol 1e-12 --out '" +
                              (dir / "long.csv").string() + "' 2>'" + err.string() + "'";
  const int status = std::system(command.c_str());
  CHECK(status != 0);  // interrupted
  const std::string text = ReadText(err);
  std::filesystem::remove(err);
  CHECK_THAT(text,
             Contains("warning: " + (dir / "long.csv").string() + " will take about 1.4 GB") &&
                 Contains("--every") && Contains("--kd-only"));
  CHECK_THAT(text, Contains("simulate: ") && Contains(" % of 1000 s"));
  CHECK(dir.EntryCount() == 1);  // long.toml: neither the CSV nor its temporary
}

TEST_CASE("simulate of a short scene prints no size warning and no progress line",
          "[cli][stream]") {
  ScratchDir dir;
  const auto run = RunMillkit("simulate " + kTwoMass + " --out '" + (dir / "r.csv").string() + "'");
  REQUIRE(run.exit_code == 0);
  CHECK_THAT(run.stderr_text, !Contains("warning") && !Contains("simulate:"));
}

TEST_CASE("simulate --help lists every registered solver with its description", "[cli]") {
  const auto run = RunMillkit("simulate --help");
  CHECK(run.exit_code == 0);
  for (const millkit::driveline::SolverInfo& info : millkit::driveline::Solvers()) {
    CHECK_THAT(run.stdout_text, Contains(std::string(info.name) + ":"));
  }
}
