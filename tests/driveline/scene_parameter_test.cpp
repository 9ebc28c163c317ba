// Named scene parameters (shared by identification, coupling optimisation and sweeps).
#include "millkit/driveline/scene_parameter.h"

#include <catch2/catch.hpp>

#include "driveline/scene_builder.h"
#include "millkit/io/input_error.h"

using namespace millkit::driveline;
using namespace millkit::driveline::testing;
using Catch::Matchers::Contains;
using millkit::InputError;

namespace {

Scene LoadedScene() {
  Scene scene = TwoMassScene(10.0, 5.0, 1e4, 10.0, 0.01, 0.2, 2000.0);
  scene.torques = {Step(1, 0.0, -100.0, 0.05, 0.01), Step(1, 0.0, -50.0, 0.06, 0.0)};
  return scene;
}

}  // namespace

TEST_CASE("Link and mass parameters read and write the scene field they name") {
  Scene scene = LoadedScene();
  const auto damping = ParseSceneParameter(scene, "shaft.damping", "test");
  damping.Set(42.0, &scene);
  CHECK(scene.links[0].damping_Nms_per_rad == 42.0);
  CHECK(damping.Get(scene) == 42.0);
  const auto inertia = ParseSceneParameter(scene, "b.inertia", "test");
  inertia.Set(7.0, &scene);
  CHECK(scene.masses[1].inertia_kg_m2 == 7.0);
}

TEST_CASE("A load is the summed final torque on the mass and setting it scales every source") {
  Scene scene = LoadedScene();
  const auto load = ParseSceneParameter(scene, "b.load", "test");
  CHECK(load.Get(scene) == -150.0);
  load.Set(-300.0, &scene);
  CHECK(scene.torques[0].values_Nm[1] == -200.0);
  CHECK(scene.torques[1].values_Nm[1] == -100.0);
}

TEST_CASE("bite_time is the earliest torque knot and setting it shifts every source") {
  Scene scene = LoadedScene();
  const auto bite = ParseSceneParameter(scene, "bite_time", "test");
  CHECK(bite.Get(scene) == 0.05);
  bite.Set(0.08, &scene);
  CHECK_THAT(scene.torques[0].times_s[0], Catch::Matchers::WithinAbs(0.08, 1e-15));
  CHECK_THAT(scene.torques[1].times_s[1], Catch::Matchers::WithinAbs(0.09, 1e-15));
}

TEST_CASE("Unknown parameter names are rejected naming the place and the accepted forms") {
  const Scene scene = LoadedScene();
  CHECK_THROWS_WITH(ParseSceneParameter(scene, "shaft.colour", "fit.toml: [[free]] #2"),
                    Contains("fit.toml: [[free]] #2") && Contains("shaft.colour") &&
                        Contains("<link>.stiffness"));
  CHECK_THROWS_WITH(ParseSceneParameter(scene, "axle.damping", "x"), Contains("no link named"));
  CHECK_THROWS_WITH(ParseSceneParameter(scene, "a.load", "x"), Contains("no load to scale"));
  CHECK_THROWS_WITH(ParseSceneParameter(scene, "damping", "x"), Contains("unknown parameter"));
}
