// The output protocol of every command (issue 13, millkit/io/output_files.h): checked before the
// work, never over an input or anything that is not a regular file, written atomically, and nothing
// left behind by an error or a signal.
#include "millkit/io/output_files.h"

#include <sys/stat.h>
#include <unistd.h>

#include <catch2/catch.hpp>
#include <filesystem>
#include <optional>
#include <string>

#include "millkit/io/atomic_file.h"
#include "millkit/io/input_error.h"
#include "support/run_cli.h"

namespace millkit {
namespace {

using Catch::Matchers::Contains;
using millkit::testing::ReadText;
using millkit::testing::RunMillkit;
using millkit::testing::ScratchDir;
using millkit::testing::SourcePath;
using millkit::testing::WriteText;
namespace fs = std::filesystem;

// No temporary file of an atomic write is left in the directory.
bool NoTemporaries(const fs::path& directory) {
  for (const auto& entry : fs::directory_iterator(directory)) {
    if (entry.path().filename().string().find(".tmp.") != std::string::npos) return false;
  }
  return true;
}

// Built with += : GCC 12 warns falsely (-Wrestrict) on "literal" + std::string.
std::string Quoted(const fs::path& path) {
  std::string text = "'";
  text += path.string();
  text += "'";
  return text;
}

}  // namespace

TEST_CASE("output check: an input under another name is refused by device and inode") {
  ScratchDir dir;
  WriteText(dir / "scene.toml", "x");
  fs::create_symlink(dir / "scene.toml", dir / "link.toml");
  CHECK_THROWS_WITH(
      CheckOutputPaths({{"--out", (dir / "link.toml").string()}}, {(dir / "scene.toml").string()}),
      Contains("--out") && Contains("one of this command's inputs"));
  CHECK_THROWS_WITH(CheckOutputPaths({{"--out", (dir / "." / "scene.toml").string()}},
                                     {(dir / "scene.toml").string()}),
                    Contains("one of this command's inputs"));
}

TEST_CASE("output check: devices FIFOs and directories are refused") {
  ScratchDir dir;
  REQUIRE(::mkfifo((dir / "pipe").c_str(), 0600) == 0);
  CHECK_THROWS_WITH(CheckOutputPaths({{"--out", (dir / "pipe").string()}}, {}), Contains("a FIFO"));
  CHECK_THROWS_WITH(CheckOutputPaths({{"--out", "/dev/null"}}, {}), Contains("a device"));
  CHECK_THROWS_WITH(CheckOutputPaths({{"--out", dir.path().string()}}, {}),
                    Contains("a directory"));
  // A symlink to a device is the device.
  fs::create_symlink("/dev/null", dir / "null_link");
  CHECK_THROWS_WITH(CheckOutputPaths({{"--plot", (dir / "null_link").string()}}, {}),
                    Contains("--plot") && Contains("a device"));
}

TEST_CASE("output check: two outputs naming one file and a missing directory are refused") {
  ScratchDir dir;
  const std::string file = (dir / "fit.json").string();
  CHECK_THROWS_WITH(CheckOutputPaths({{"--out", file}, {"--plot", file}}, {}),
                    Contains("--out") && Contains("--plot") && Contains("same file"));
  CHECK_THROWS_WITH(CheckOutputPaths({{"--out", (dir / "none" / "x.csv").string()}}, {}),
                    Contains("does not exist"));
  CHECK_NOTHROW(CheckOutputPaths({{"--out", file}, {"--plot", ""}}, {}));
}

TEST_CASE("output check: one new file spelled two ways relative to the working directory") {
  // "fit.json" and "./fit.json" before the file exists: both outputs would be written to one
  // file, the second rename failing after the first had landed.
  ScratchDir dir;
  fs::create_directory(dir / "sub");
  // The working directory is the scratch directory for this test only, whatever it throws.
  struct WorkingDirectory {
    fs::path before = fs::current_path();
    explicit WorkingDirectory(const fs::path& to) { fs::current_path(to); }
    ~WorkingDirectory() { fs::current_path(before); }
    WorkingDirectory(const WorkingDirectory&) = delete;
    WorkingDirectory& operator=(const WorkingDirectory&) = delete;
  };
  std::optional<WorkingDirectory> inside(std::in_place, dir.path());
  const auto check = [](const std::string& a, const std::string& b) {
    try {
      CheckOutputPaths({{"--out", a}, {"--trace", b}}, {});
    } catch (const InputError& error) {
      return std::string(error.what());
    }
    return std::string();
  };
  const std::string plain = check("fit.json", "./fit.json");
  const std::string up = check("sub/../fit.json", "fit.json");
  const std::string apart = check("fit.json", "sub/fit.json");
  inside.reset();
  CHECK_THAT(plain, Contains("--out") && Contains("--trace") && Contains("same file"));
  CHECK_THAT(up, Contains("same file"));
  CHECK(apart.empty());
  CHECK_FALSE(fs::exists(dir / "fit.json"));
}

TEST_CASE("an atomic write through a symlink replaces its target and keeps the link") {
  ScratchDir dir;
  WriteText(dir / "target.csv", "old\n");
  fs::create_symlink(dir / "target.csv", dir / "link.csv");
  WriteFileAtomically(dir / "link.csv", "new\n");
  CHECK(fs::is_symlink(fs::symlink_status(dir / "link.csv")));
  CHECK(ReadText(dir / "target.csv") == "new\n");
  CHECK(NoTemporaries(dir.path()));
}

TEST_CASE("an atomic write through a link to a file not made yet makes it and keeps the link") {
  ScratchDir dir;
  fs::create_directory(dir / "runs");
  // latest.csv -> runs/42.csv (not there yet), reached through a second link.
  fs::create_symlink("runs/42.csv", dir / "latest.csv");
  fs::create_symlink("latest.csv", dir / "view.csv");
  CHECK_NOTHROW(CheckOutputPaths({{"--out", (dir / "view.csv").string()}}, {}));
  // The two names of one new file are one output.
  CHECK_THROWS_WITH(CheckOutputPaths({{"--out", (dir / "view.csv").string()},
                                      {"--plot", (dir / "runs" / "42.csv").string()}},
                                     {}),
                    Contains("same file"));
  WriteFileAtomically(dir / "view.csv", "new\n");
  CHECK(fs::is_symlink(fs::symlink_status(dir / "view.csv")));
  CHECK(fs::is_symlink(fs::symlink_status(dir / "latest.csv")));
  CHECK(ReadText(dir / "runs" / "42.csv") == "new\n");
  CHECK(NoTemporaries(dir.path()));
  CHECK(NoTemporaries(dir / "runs"));
}

TEST_CASE("output check: a link into a missing directory and a loop of links are refused") {
  ScratchDir dir;
  fs::create_symlink("none/x.csv", dir / "lost.csv");
  CHECK_THROWS_WITH(CheckOutputPaths({{"--out", (dir / "lost.csv").string()}}, {}),
                    Contains("--out") && Contains("does not exist"));
  fs::create_symlink("b.csv", dir / "a.csv");
  fs::create_symlink("a.csv", dir / "b.csv");
  CHECK_THROWS_AS(CheckOutputPaths({{"--out", (dir / "a.csv").string()}}, {}), InputError);
  CHECK_THROWS_WITH(CheckOutputPaths({{"--out", (dir / "a.csv").string()}}, {}),
                    Contains("--out") && Contains("cannot be resolved"));
  CHECK(fs::is_symlink(fs::symlink_status(dir / "a.csv")));
}

TEST_CASE("an atomic writer refuses a FIFO and leaves it one") {
  ScratchDir dir;
  REQUIRE(::mkfifo((dir / "pipe").c_str(), 0600) == 0);
  CHECK_THROWS_AS(AtomicFile(dir / "pipe"), InputError);
  struct stat info {};
  REQUIRE(::stat((dir / "pipe").c_str(), &info) == 0);
  CHECK(S_ISFIFO(info.st_mode));
  CHECK(NoTemporaries(dir.path()));
}

TEST_CASE("no command writes over one of its inputs") {
  ScratchDir dir;
  const auto copy = [&](const std::string& relative, const std::string& name) {
    fs::copy_file(SourcePath(relative), dir / name);
    return dir / name;
  };
  const auto scene = copy("datasets/scenes/mill5_bite.toml", "scene.toml");
  const auto record = copy("datasets/records/mill5_two_spindles.csv", "record.csv");
  const auto config = copy("datasets/records/mill5_two_spindles.fit.toml", "fit.toml");
  const auto spec = copy("datasets/records/mill5_two_spindles.spec.toml", "spec.toml");
  const auto geometry = copy("datasets/leveller/leveller_default.toml", "geometry.toml");
  const auto angles = copy("datasets/leveller/angles.csv", "angles.csv");
  const auto strips = copy("datasets/leveller/strips.csv", "strips.csv");
  const auto sweep = copy("datasets/studies/mill5_lhs.toml", "sweep.toml");
  const auto coupling = copy("datasets/studies/mill5_coupling.toml", "coupling.toml");
  const auto balancer = copy("datasets/balancer/seed_002_stand950.toml", "balancer.toml");
  const std::vector<std::pair<std::string, fs::path>> runs = {
      {"simulate " + Quoted(scene) + " --out " + Quoted(scene), scene},
      {"identify " + Quoted(scene) + " --data " + Quoted(record) + " --config " + Quoted(config) +
           " --out " + Quoted(record),
       record},
      {"identify " + Quoted(scene) + " --data " + Quoted(record) + " --config " + Quoted(config) +
           " --out " + Quoted(dir / "fit.json") + " --plot " + Quoted(config),
       config},
      {"synthesize " + Quoted(scene) + " --spec " + Quoted(spec) + " --out " + Quoted(spec), spec},
      {"leveller forward --geometry " + Quoted(geometry) + " --in " + Quoted(angles) + " --out " +
           Quoted(angles),
       angles},
      {"leveller table --geometry " + Quoted(geometry) + " --strips " + Quoted(strips) + " --out " +
           Quoted(geometry),
       geometry},
      {"sweep " + Quoted(scene) + " --config " + Quoted(sweep) + " --out " + Quoted(sweep), sweep},
      {"coupling " + Quoted(scene) + " --config " + Quoted(coupling) + " --out " + Quoted(coupling),
       coupling},
      {"balancer --config " + Quoted(balancer) + " --out " + Quoted(balancer), balancer},
  };
  for (const auto& [arguments, input] : runs) {
    const std::string before = ReadText(input);
    const auto run = RunMillkit(arguments);
    INFO(arguments << "\n" << run.stderr_text);
    CHECK(run.exit_code == 2);
    CHECK_THAT(run.stderr_text, Contains("one of this command's inputs"));
    CHECK(ReadText(input) == before);
    CHECK_FALSE(fs::exists(dir / "fit.json"));
    CHECK(NoTemporaries(dir.path()));
  }
}

TEST_CASE("identify with --plot and --out naming one file exits 2 and writes nothing") {
  ScratchDir dir;
  const auto run =
      RunMillkit("identify " + Quoted(SourcePath("datasets/scenes/mill5_bite.toml")) + " --data " +
                 Quoted(SourcePath("datasets/records/mill5_two_spindles.csv")) + " --out " +
                 Quoted(dir / "x") + " --plot " + Quoted(dir / "x"));
  CHECK(run.exit_code == 2);
  CHECK_THAT(run.stderr_text, Contains("same file"));
  CHECK_FALSE(fs::exists(dir / "x"));
  CHECK(NoTemporaries(dir.path()));
}

TEST_CASE("SIGTERM in the middle of a fit leaves nothing behind") {
  ScratchDir dir;
  // The bundled record without its config: the default search runs for seconds.
  const std::string command =
      std::string("'") + MILLKIT_BINARY + "' identify " +
      Quoted(SourcePath("datasets/scenes/mill5_bite.toml")) + " --data " +
      Quoted(SourcePath("datasets/records/mill5_two_spindles.csv")) + " --out " +
      Quoted(dir / "fit.json") + " --plot " + Quoted(dir / "fit.svg") +
      " >/dev/null 2>&1 & pid=$!; sleep 0.5; kill -TERM $pid; wait $pid; echo $? > " +
      Quoted(dir / "status");
  REQUIRE(std::system(command.c_str()) == 0);
  INFO("exit status " << ReadText(dir / "status"));
  CHECK(std::stoi(ReadText(dir / "status")) == 128 + SIGTERM);
  fs::remove(dir / "status");
  CHECK_FALSE(fs::exists(dir / "fit.json"));
  CHECK_FALSE(fs::exists(dir / "fit.svg"));
  CHECK(NoTemporaries(dir.path()));
}

}  // namespace millkit
