// The cardan cross pin (cardan_cross.h): consistency of the minimum diameter with the allowable
// stress, the safety factor product and the preconditions.
#include "millkit/balancer/cardan_cross.h"

#include <catch2/catch.hpp>
#include <cmath>
#include <stdexcept>

namespace bal = millkit::balancer;
using Catch::Matchers::WithinRel;

namespace {
constexpr double kRoundOff = 1e-12;
constexpr double kSeedWeightShare_N = 90700.8;  // seed 002 §6
}  // namespace

TEST_CASE("A pin of exactly the minimum diameter is stressed to the allowable stress", "[cross]") {
  bal::CardanCross cross;
  const auto minimum = bal::CalcCrossPin(kSeedWeightShare_N, cross);
  cross.pin_diameter_m = minimum.min_diameter_m;
  const auto at_minimum = bal::CalcCrossPin(kSeedWeightShare_N, cross);
  CHECK_THAT(at_minimum.stress_at_adopted_Pa, WithinRel(at_minimum.allowable_stress_Pa, 1e-9));
}

TEST_CASE("The safety factor is the product S1 S2 S3 and divides the strength", "[cross]") {
  bal::CardanCross cross;
  cross.s1 = 1.2;
  cross.s2 = 1.3;
  cross.s3 = 1.1;
  const auto r = bal::CalcCrossPin(kSeedWeightShare_N, cross);
  CHECK_THAT(r.safety_factor, WithinRel(1.2 * 1.3 * 1.1, kRoundOff));
  CHECK_THAT(r.allowable_stress_Pa, WithinRel(1370.0e6 / (1.2 * 1.3 * 1.1), kRoundOff));
}

TEST_CASE("A larger safety factor asks for a thicker pin, by the cube root", "[cross]") {
  // d ∝ cbrt(S): doubling S multiplies d by 2^(1/3).
  bal::CardanCross low;
  low.s1 = low.s2 = low.s3 = 1.0;
  bal::CardanCross high = low;
  high.s1 = 2.0;
  const double d_low = bal::CalcCrossPin(kSeedWeightShare_N, low).min_diameter_m;
  const double d_high = bal::CalcCrossPin(kSeedWeightShare_N, high).min_diameter_m;
  CHECK_THAT(d_high / d_low, WithinRel(std::cbrt(2.0), kRoundOff));
}

TEST_CASE("A pin thinner than the minimum fails the check", "[cross]") {
  bal::CardanCross cross;
  cross.pin_diameter_m = 0.050;  // below the 55.9 mm the seed case needs at S = 3.375
  const auto r = bal::CalcCrossPin(kSeedWeightShare_N, cross);
  CHECK(r.stress_at_adopted_Pa > r.allowable_stress_Pa);
  CHECK_FALSE(r.adopted_diameter_passes);
}

TEST_CASE("A safety factor below one is refused", "[cross]") {
  bal::CardanCross cross;
  cross.s2 = 0.9;
  CHECK_THROWS_AS(bal::CalcCrossPin(kSeedWeightShare_N, cross), std::invalid_argument);
}
