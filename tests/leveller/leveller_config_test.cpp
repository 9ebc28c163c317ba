// Leveller configuration TOML (SPEC.md §6.2): defaults, degenerate geometry, bad keys.
#include "millkit/leveller/leveller_config.h"

#include <catch2/catch.hpp>

#include "millkit/io/input_error.h"
#include "support/run_cli.h"

using namespace millkit::leveller;
using Catch::Matchers::Contains;
using millkit::testing::ScratchDir;
using millkit::testing::SourcePath;
using millkit::testing::WriteText;

TEST_CASE("The bundled default TOML holds the SPEC's geometry and machine", "[leveller][config]") {
  const LevellerConfig config =
      LoadLevellerConfig(SourcePath("datasets/leveller/leveller_default.toml"));
  const LevellerConfig builtin = DefaultLevellerConfig();
  CHECK(config.linkage.a.y == builtin.linkage.a.y);
  CHECK(config.linkage.hk_mm == builtin.linkage.hk_mm);
  CHECK(config.linkage.cg_mm == builtin.linkage.cg_mm);
  CHECK(config.linkage.g0.x == builtin.linkage.g0.x);
  CHECK(config.machine.roll_diameter_mm == builtin.machine.roll_diameter_mm);
  CHECK(config.machine.efficiency == builtin.machine.efficiency);
  CHECK(config.hydraulic.bg_min_mm == builtin.hydraulic.bg_min_mm);
}

TEST_CASE("Rods that cannot close are rejected on load naming the key", "[leveller][config]") {
  ScratchDir dir;
  WriteText(dir / "short_gj.toml", "[linkage]\ngj_mm = 100.0\n");
  REQUIRE_THROWS_WITH(
      LoadLevellerConfig(dir / "short_gj.toml"),
      Contains("key 'gj_mm'") && Contains("rods cannot close") && Contains("(line 2)"));
  WriteText(dir / "short_hk.toml", "[linkage]\nhk_mm = 200.0\n");
  REQUIRE_THROWS_WITH(LoadLevellerConfig(dir / "short_hk.toml"),
                      Contains("key 'hk_mm'") && Contains("rods cannot close"));
}

TEST_CASE("A degenerate beam is rejected naming the pin", "[leveller][config]") {
  ScratchDir dir;
  WriteText(dir / "pins.toml", "[linkage]\nf0_mm = [100.0, 180.0]\n");
  REQUIRE_THROWS_WITH(LoadLevellerConfig(dir / "pins.toml"), Contains("key 'f0_mm'"));
}

TEST_CASE("Unknown keys, negative lengths and bad efficiencies are rejected",
          "[leveller][config]") {
  ScratchDir dir;
  WriteText(dir / "unknown.toml", "[linkage]\ngj = 540.0\n");
  REQUIRE_THROWS_WITH(LoadLevellerConfig(dir / "unknown.toml"),
                      Contains("key 'gj'") && Contains("unknown key"));
  WriteText(dir / "table.toml", "[linkages]\n");
  REQUIRE_THROWS_WITH(LoadLevellerConfig(dir / "table.toml"), Contains("unknown key"));
  WriteText(dir / "negative.toml", "[linkage]\ncg_mm = -5\n");
  REQUIRE_THROWS_WITH(LoadLevellerConfig(dir / "negative.toml"), Contains("must be > 0"));
  WriteText(dir / "eta.toml", "[machine]\nefficiency = 1.5\n");
  REQUIRE_THROWS_WITH(LoadLevellerConfig(dir / "eta.toml"),
                      Contains("key 'efficiency'") && Contains("(0, 1]"));
}

TEST_CASE("A geometry built in code is validated by the Linkage constructor",
          "[leveller][config]") {
  LinkageGeometry geometry;
  geometry.cg_mm = 10.0;
  REQUIRE_THROWS_AS(ValidateLinkage(geometry, "test"), millkit::InputError);
}
