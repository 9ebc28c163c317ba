// Undamped natural frequencies with the gaps closed: closed forms and a cross-check.
#include "millkit/driveline/natural_frequencies.h"

#include <catch2/catch.hpp>
#include <cmath>

#include "driveline/scene_builder.h"
#include "millkit/driveline/model.h"
#include "support/study_support.h"

using namespace millkit::driveline;
using Catch::Matchers::WithinAbs;
using Catch::Matchers::WithinRel;
using millkit::driveline::testing::kPi;
using millkit::driveline::testing::TwoMassScene;

namespace {
constexpr double kEigenTolerance = 1e-12;  // relative, symmetric eigensolver on 2–5 masses
}

TEST_CASE("two masses: one rigid-body mode and sqrt(c (1/J1 + 1/J2)) / 2π", "[coupling][modes]") {
  const Scene scene = TwoMassScene(1000.0, 500.0, 3.0e7, 100.0, 0.01, 0.1, 1000.0);
  const auto hz = NaturalFrequenciesHz(scene);
  REQUIRE(hz.size() == 2);
  CHECK_THAT(hz[0], WithinAbs(0.0, 1e-6));
  const double expected = std::sqrt(3.0e7 * (1.0 / 1000.0 + 1.0 / 500.0)) / (2.0 * kPi);
  CHECK_THAT(hz[1], WithinRel(expected, kEigenTolerance));
  CHECK_THAT(LowestNaturalFrequencyHz(scene), WithinRel(expected, kEigenTolerance));
}

TEST_CASE("a gear stage counts: ω² = c (1/(J1 i²) + 1/J2), as the model's own mode",
          "[coupling][modes]") {
  // J1 = 10 on the fast side of a ratio-3 stage, c = 1e6 N*m/rad in the slow side's units:
  // 28.07 Hz (without the ratio: 55.13 Hz, the coupling limit's old answer).
  Scene scene = TwoMassScene(10.0, 50.0, 1.0e6, 0.0, 0.0, 0.1, 1000.0);
  scene.links[0].ratio = 3.0;
  const double expected = std::sqrt(1.0e6 * (1.0 / (10.0 * 9.0) + 1.0 / 50.0)) / (2.0 * kPi);
  CHECK_THAT(expected, WithinAbs(28.07, 0.005));
  CHECK_THAT(LowestNaturalFrequencyHz(scene), WithinRel(expected, kEigenTolerance));
  const Scene reduced = ReducedScene(scene);
  CHECK_THAT(HighestModeHz(reduced, ReduceToBand(reduced)), WithinRel(expected, kEigenTolerance));
}

TEST_CASE("three equal masses in a chain: ω² = c/J and 3c/J", "[coupling][modes]") {
  Scene scene = TwoMassScene(200.0, 200.0, 5.0e6, 0.0, 0.0, 0.1, 1000.0);
  millkit::testing::AppendMass(&scene, "c", 200.0, "second", 1);
  const auto hz = NaturalFrequenciesHz(scene);
  REQUIRE(hz.size() == 3);
  const double w2 = 5.0e6 / 200.0;
  CHECK_THAT(hz[1], WithinRel(std::sqrt(w2) / (2.0 * kPi), kEigenTolerance));
  CHECK_THAT(hz[2], WithinRel(std::sqrt(3.0 * w2) / (2.0 * kPi), kEigenTolerance));
}

TEST_CASE("the highest mode agrees with the model's HighestModeHz (linear contact, c per link)",
          "[coupling][modes]") {
  // HighestModeHz uses 2c for limited-law links with a gap; with the linear law it uses c, as here.
  Scene scene = LoadScene(millkit::testing::SourcePath("datasets/scenes/mill5_bite.toml"));
  scene.contact = ContactLaw::kLinear;
  const double model_hz = HighestModeHz(scene, ReduceToBand(scene));
  CHECK_THAT(NaturalFrequenciesHz(scene).back(), WithinRel(model_hz, kEigenTolerance));
}

TEST_CASE("the lowest elastic frequency does not fall when any link stiffens",
          "[coupling][modes]") {
  const Scene base = LoadScene(millkit::testing::SourcePath("datasets/scenes/mill5_bite.toml"));
  const double f1 = LowestNaturalFrequencyHz(base);
  for (size_t l = 0; l < base.links.size(); ++l) {
    Scene stiffer = base;
    stiffer.links[l].stiffness_Nm_per_rad *= 1.5;
    CHECK(LowestNaturalFrequencyHz(stiffer) >= f1 * (1.0 - kEigenTolerance));
  }
}
