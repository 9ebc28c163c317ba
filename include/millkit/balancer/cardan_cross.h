// Cross of the cardan joint that hangs a balancer rod on the spindle traverse: bending of its
// largest pin and the minimum pin diameter for a chosen safety factor. Seed 002 §6 (figs. 7 and 8
// are not available), restated in SPEC.md §7. SI: N, m, Pa, N·m.
#pragma once

#include "millkit/balancer/balancer_input.h"

namespace millkit::balancer {

struct CrossPinCheck {
  double reaction_N = 0.0;               // N = G / 2 on each pin of the pair
  double moment_Nm = 0.0;                // Mи = N a
  double safety_factor = 0.0;            // S = S1 S2 S3
  double allowable_stress_Pa = 0.0;      // [σи] = σв / S
  double min_diameter_m = 0.0;           // d = cbrt(Mи / (0.1 [σи]))
  double stress_at_adopted_Pa = 0.0;     // σи = Mи / (0.1 d³) at the adopted diameter
  bool adopted_diameter_passes = false;  // adopted d >= minimum d (equivalently σи <= [σи])
};

// The largest pin as a cantilever loaded by half the rod's weight share (seed 002 §6):
//   N = G / 2,   Mи = N a,   σи = Mи / W <= [σи],   W = π d³ / 32 ≈ 0.1 d³,
//   [σи] = σв / S,   S = S1 S2 S3,   d = cbrt(Mи / (0.1 [σи])).
// W is the axial section modulus of a round pin (the seed calls it "polar"; the polar modulus is
// π d³ / 16). The seed rounds π/32 = 0.0982 up to 0.1 and so do we: the printed pin formula uses
// 0.1. Seed ranges: S1 = 1…1.5, S2 = 1.2…1.5, S3 = 1…1.5.
// Requires G >= 0, a >= 0, d > 0, σв > 0 and S1, S2, S3 >= 1; throws std::invalid_argument
// otherwise.
CrossPinCheck CalcCrossPin(double rod_weight_share_N, const CardanCross& cross);

}  // namespace millkit::balancer
