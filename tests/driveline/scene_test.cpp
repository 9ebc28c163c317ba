// Scene loading and validation (SPEC §2.6): every rule has a test naming the key in the error.
#include "millkit/driveline/scene.h"

#include <catch2/catch.hpp>

#include "millkit/driveline/model.h"
#include "millkit/io/input_error.h"
#include "support/run_cli.h"

using namespace millkit::driveline;
using Catch::Matchers::Contains;
using millkit::InputError;
using millkit::testing::ScratchDir;
using millkit::testing::WriteText;

namespace {

const char* kValidScene = R"(
[scene]
name = "t"
duration = 0.1
sample_rate = 2000
contact = "limited"
[initial]
speed = 5.0
[[mass]]
name = "motor"
inertia = 10.0
[[mass]]
name = "roll"
inertia = 5.0
[[link]]
name = "spindle"
between = ["motor", "roll"]
stiffness = 1.0e4
damping = 10.0
backlash = 0.01
gap_position = 0.5
[[torque]]
at = "roll"
after = -100.0
start = 0.01
rise = 0.002
)";

std::string Replace(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  REQUIRE(at != std::string::npos);
  return text.replace(at, from.size(), to);
}

// Loads `text` from a scratch file; returns the InputError message ("" when it loads).
std::string LoadError(const std::string& text) {
  ScratchDir dir;
  const auto path = (dir / "scene.toml").string();
  WriteText(path, text);
  try {
    LoadScene(path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST_CASE("A valid scene loads with every value", "[scene]") {
  ScratchDir dir;
  WriteText(dir / "s.toml", kValidScene);
  const Scene scene = LoadScene((dir / "s.toml").string());
  REQUIRE(scene.masses.size() == 2);
  CHECK(scene.links[0].backlash_rad == 0.01);
  CHECK(scene.links[0].gap_position == 0.5);
  CHECK(scene.initial_speed_rad_per_s == 5.0);
  CHECK(scene.torques[0].ValueAt(0.011) == Approx(-50.0));
  CHECK(scene.SampleCount() == 201);
}

TEST_CASE("A TOML syntax error names the file and line", "[scene][bad_input]") {
  CHECK_THAT(LoadError("[scene\nduration = 1"), Contains("scene.toml:1:") && Contains("TOML"));
}

TEST_CASE("An unknown key is rejected naming it", "[scene][bad_input]") {
  CHECK_THAT(LoadError(Replace(kValidScene, "damping = 10.0", "dampin = 10.0")),
             Contains("key 'dampin'") && Contains("unknown key"));
  CHECK_THAT(LoadError(std::string(kValidScene) + "[extra]\na = 1\n"),
             Contains("key 'extra'") && Contains("unknown key"));
}

TEST_CASE("A link to a missing mass is rejected", "[scene][bad_input]") {
  CHECK_THAT(LoadError(Replace(kValidScene, R"(["motor", "roll"])", R"(["motor", "rol"])")),
             Contains("key 'between'") && Contains("no [[mass]] named 'rol'"));
}

TEST_CASE("A topology that is not a tree is rejected", "[scene][bad_input]") {
  const std::string third_mass = "[[mass]]\nname = \"extra\"\ninertia = 1.0\n";
  CHECK_THAT(LoadError(std::string(kValidScene) + third_mass), Contains("must form a tree"));
  const std::string loop = third_mass +
                           "[[link]]\nname = \"l2\"\nbetween = [\"motor\", \"roll\"]\n"
                           "stiffness = 1.0\n";
  CHECK_THAT(LoadError(std::string(kValidScene) + loop), Contains("closes a loop"));
  CHECK_THAT(LoadError(Replace(kValidScene, R"(["motor", "roll"])", R"(["roll", "roll"])")),
             Contains("cannot join a mass to itself"));
}

TEST_CASE("Non-positive inertia or stiffness is rejected", "[scene][bad_input]") {
  CHECK_THAT(LoadError(Replace(kValidScene, "inertia = 5.0", "inertia = 0.0")),
             Contains("key 'inertia'") && Contains("must be > 0"));
  CHECK_THAT(LoadError(Replace(kValidScene, "stiffness = 1.0e4", "stiffness = -1.0e4")),
             Contains("key 'stiffness'") && Contains("must be > 0"));
}

TEST_CASE("Negative damping or backlash is rejected", "[scene][bad_input]") {
  CHECK_THAT(LoadError(Replace(kValidScene, "damping = 10.0", "damping = -1.0")),
             Contains("key 'damping'") && Contains("must be >= 0"));
  CHECK_THAT(LoadError(Replace(kValidScene, "backlash = 0.01", "backlash = -0.01")),
             Contains("key 'backlash'") && Contains("must be >= 0"));
}

TEST_CASE("A link ratio loads, defaults to 1 and must be positive", "[scene][bad_input]") {
  ScratchDir dir;
  WriteText(dir / "s.toml",
            Replace(kValidScene, "gap_position = 0.5", "gap_position = 0.5\nratio = 2.5"));
  CHECK(LoadScene((dir / "s.toml").string()).links[0].ratio == 2.5);
  WriteText(dir / "t.toml", kValidScene);
  CHECK(LoadScene((dir / "t.toml").string()).links[0].ratio == 1.0);
  for (const char* bad : {"ratio = 0.0", "ratio = -3.0"}) {
    CHECK_THAT(LoadError(Replace(kValidScene, "gap_position = 0.5",
                                 std::string("gap_position = 0.5\n") + bad)),
               Contains("scene.toml") && Contains("key 'ratio'") && Contains("must be > 0"));
  }
}

TEST_CASE("A gap_position outside [-1, 1] is rejected", "[scene][bad_input]") {
  CHECK_THAT(LoadError(Replace(kValidScene, "gap_position = 0.5", "gap_position = 1.5")),
             Contains("key 'gap_position'") && Contains("[-1, 1]"));
}

TEST_CASE("An unknown contact law is rejected", "[scene][bad_input]") {
  CHECK_THAT(LoadError(Replace(kValidScene, R"("limited")", R"("elastic")")),
             Contains("key 'contact'") && Contains("limited, no_pull or linear"));
}

TEST_CASE("Missing required keys are named", "[scene][bad_input]") {
  CHECK_THAT(LoadError(Replace(kValidScene, "duration = 0.1", "")),
             Contains("key 'duration'") && Contains("is required"));
  CHECK_THAT(LoadError(Replace(kValidScene, "stiffness = 1.0e4", "")),
             Contains("key 'stiffness'") && Contains("is required"));
}

TEST_CASE("A sample rate that cannot resolve the fastest mode is rejected", "[scene][bad_input]") {
  // Fastest mode with the limited law's doubled spring: sqrt(2e4 (1/10 + 1/5))/2π = 12.3 Hz;
  // 40 Hz < 4 × 12.3 Hz.
  CHECK_THAT(LoadError(Replace(kValidScene, "sample_rate = 2000", "sample_rate = 40")),
             Contains("key 'sample_rate'") && Contains("fastest mode") && Contains("band"));
}

TEST_CASE("A torque table must have time and one value column, increasing in time",
          "[scene][bad_input]") {
  ScratchDir dir;
  WriteText(dir / "load.csv", "time,torque\n0,0\n0.05,-10\n0.04,-20\n");
  std::string text =
      Replace(kValidScene, "after = -100.0\nstart = 0.01\nrise = 0.002", "table = \"load.csv\"");
  WriteText(dir / "s.toml", text);
  REQUIRE_THROWS_WITH(LoadScene((dir / "s.toml").string()),
                      Contains("load.csv: line 4") && Contains("increase strictly"));
  WriteText(dir / "load.csv", "time,torque\n0,0\n0.05,abc\n");
  REQUIRE_THROWS_WITH(LoadScene((dir / "s.toml").string()),
                      Contains("load.csv: line 3, column 'torque'"));
  // A units row in ms would have read 50 ms as 50 s: refused, naming the unit.
  WriteText(dir / "load.csv", "time,torque\nms,N*m\n0,0\n50,-10\n");
  REQUIRE_THROWS_WITH(
      LoadScene((dir / "s.toml").string()),
      Contains("load.csv: line 2 (units row), column 'time'") && Contains("unit 'ms'"));
  WriteText(dir / "load.csv", "time;torque\ns;N*m\n0;0\n0,05;-10\n");
  REQUIRE_NOTHROW(LoadScene((dir / "s.toml").string()));
}

TEST_CASE("A drive with bad gains is rejected", "[scene][bad_input]") {
  const std::string drive =
      "[drive]\nat = \"motor\"\nkp = 0.0\nki = 0.0\nlag = 0.01\nlimit = 1e3\n";
  CHECK_THAT(LoadError(std::string(kValidScene) + drive), Contains("kp and ki cannot both be 0"));
  const std::string lag = "[drive]\nat = \"motor\"\nkp = 1.0\nki = 0.0\nlag = 0.0\nlimit = 1e3\n";
  CHECK_THAT(LoadError(std::string(kValidScene) + lag), Contains("key 'lag'"));
}

TEST_CASE("A missing scene file is a clear error", "[scene][bad_input]") {
  REQUIRE_THROWS_WITH(LoadScene("/no/such/scene.toml"), Contains("file not found"));
}
