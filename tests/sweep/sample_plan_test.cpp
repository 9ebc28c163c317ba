// Sample plans: full grids and seeded Latin hypercubes.
#include "millkit/sweep/sample_plan.h"

#include <catch2/catch.hpp>
#include <cmath>
#include <set>

#include "driveline/scene_builder.h"

using namespace millkit::sweep;
using millkit::driveline::ParseSceneParameter;
using millkit::driveline::testing::TwoMassScene;

namespace {

SweepDimension Dimension(const char* name, double lower, double upper, int points,
                         Scale scale = Scale::kLinear) {
  const auto scene = TwoMassScene(1.0, 1.0, 1e6, 10.0, 0.01, 0.1, 1000.0);
  SweepDimension d;
  d.parameter = ParseSceneParameter(scene, name, "test");
  d.lower = lower;
  d.upper = upper;
  d.points = points;
  d.scale = scale;
  return d;
}

}  // namespace

TEST_CASE("a grid holds every combination, the first parameter varying slowest", "[sweep]") {
  SweepDimension damping = Dimension("shaft.damping", 0.0, 1.0, 3);
  SweepDimension backlash = Dimension("shaft.backlash", 0.0, 0.0, 0);
  backlash.values = {0.02, 0.01};
  const CaseList cases = GridCases({damping, backlash});
  const CaseList expected = {{0.0, 0.02}, {0.0, 0.01}, {0.5, 0.02},
                             {0.5, 0.01}, {1.0, 0.02}, {1.0, 0.01}};
  CHECK(cases == expected);
}

TEST_CASE("log grid values are geometric with both ends exact", "[sweep]") {
  const auto values = Dimension("shaft.stiffness", 1e6, 1e8, 5, Scale::kLog).GridValues();
  REQUIRE(values.size() == 5);
  CHECK(values.front() == 1e6);
  CHECK(values.back() == 1e8);
  for (size_t i = 1; i < values.size(); ++i) {
    CHECK_THAT(values[i] / values[i - 1], Catch::Matchers::WithinRel(std::sqrt(10.0), 1e-14));
  }
}

TEST_CASE("a Latin hypercube puts exactly one case in each stratum of every dimension", "[sweep]") {
  const int n = 64;
  const std::vector<SweepDimension> dims = {Dimension("shaft.damping", 100.0, 900.0, 0),
                                            Dimension("shaft.stiffness", 1e5, 1e9, 0, Scale::kLog),
                                            Dimension("shaft.gap_position", -1.0, 1.0, 0)};
  const CaseList cases = LatinHypercubeCases(dims, n, 7);
  REQUIRE(cases.size() == static_cast<size_t>(n));
  for (size_t d = 0; d < dims.size(); ++d) {
    std::set<int> strata;
    for (const auto& c : cases) {
      REQUIRE(c[d] >= dims[d].lower);
      REQUIRE(c[d] <= dims[d].upper);
      strata.insert(static_cast<int>(std::floor(dims[d].ToUnit(c[d]) * n)));
    }
    CHECK(strata.size() == static_cast<size_t>(n));
  }
}

TEST_CASE("a Latin hypercube is reproducible from its seed and changes with it", "[sweep]") {
  const std::vector<SweepDimension> dims = {Dimension("shaft.damping", 0.0, 1.0, 0),
                                            Dimension("shaft.backlash", 0.0, 0.1, 0)};
  CHECK(LatinHypercubeCases(dims, 20, 42) == LatinHypercubeCases(dims, 20, 42));
  CHECK(LatinHypercubeCases(dims, 20, 42) != LatinHypercubeCases(dims, 20, 43));
}

TEST_CASE("FromUnit and ToUnit invert each other and FromUnit stays inside the range", "[sweep]") {
  const SweepDimension d = Dimension("shaft.stiffness", 3e5, 7e7, 0, Scale::kLog);
  for (double u : {0.0, 1e-17, 0.25, 0.5, 0.9, 1.0 - 1e-16, 1.0}) {
    const double v = d.FromUnit(u);
    CHECK(v >= d.lower);
    CHECK(v <= d.upper);
    CHECK_THAT(d.ToUnit(v), Catch::Matchers::WithinAbs(u, 1e-14));
  }
}
