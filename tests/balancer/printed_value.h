// Matching a computed value against a number a seed prints: the value is reproduced when it rounds
// to the printed digits, i.e. lies within half a unit of the last printed digit.
#pragma once

#include <catch2/catch.hpp>
#include <cmath>

namespace millkit::balancer::testing {

inline Catch::Matchers::Floating::WithinAbsMatcher RoundsTo(double printed, int decimals) {
  const double half_unit_of_last_digit = 0.5 * std::pow(10.0, -decimals);
  return Catch::Matchers::WithinAbs(printed, half_unit_of_last_digit);
}

}  // namespace millkit::balancer::testing
