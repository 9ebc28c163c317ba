#include "millkit/balancer/cardan_cross.h"

#include <cmath>
#include <stdexcept>
#include <string>

#include "millkit/io/number_format.h"

namespace millkit::balancer {
namespace {

// W ≈ 0.1 d³ for a round section in bending (π/32 rounded up), seed 002 §6.
constexpr double kSectionModulusFactor = 0.1;

void Require(bool holds, const std::string& rule) {
  if (!holds) throw std::invalid_argument("CalcCrossPin: " + rule);
}

}  // namespace

CrossPinCheck CalcCrossPin(double rod_weight_share_N, const CardanCross& cross) {
  Require(rod_weight_share_N >= 0.0,
          "rod_weight_share_N must be >= 0 (got " + FormatNumber(rod_weight_share_N) + ")");
  Require(cross.pin_arm_m >= 0.0,
          "pin_arm_m must be >= 0 (got " + FormatNumber(cross.pin_arm_m) + ")");
  Require(cross.pin_diameter_m > 0.0,
          "pin_diameter_m must be > 0 (got " + FormatNumber(cross.pin_diameter_m) + ")");
  Require(cross.ultimate_strength_Pa > 0.0, "ultimate_strength_Pa must be > 0 (got " +
                                                FormatNumber(cross.ultimate_strength_Pa) + ")");
  Require(cross.s1 >= 1.0 && cross.s2 >= 1.0 && cross.s3 >= 1.0, "s1, s2, s3 must be >= 1");

  CrossPinCheck r;
  r.reaction_N = rod_weight_share_N / 2.0;
  r.moment_Nm = r.reaction_N * cross.pin_arm_m;
  r.safety_factor = cross.s1 * cross.s2 * cross.s3;
  r.allowable_stress_Pa = cross.ultimate_strength_Pa / r.safety_factor;
  r.min_diameter_m = std::cbrt(r.moment_Nm / (kSectionModulusFactor * r.allowable_stress_Pa));
  const double d = cross.pin_diameter_m;
  r.stress_at_adopted_Pa = r.moment_Nm / (kSectionModulusFactor * d * d * d);
  r.adopted_diameter_passes = d >= r.min_diameter_m;
  return r;
}

}  // namespace millkit::balancer
