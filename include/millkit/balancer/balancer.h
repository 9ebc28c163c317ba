// The spindle balancing device calculator: every load and check of seed 002 for one device, and
// the idle-gap assessment of seed 000 for its balancing setting. SPEC.md §7.
//
//   support  P1, P2 (roller_support.h)       roller  q, N1, N2, M(a), M(a + b)
//   contact  Pр, Pв, σсм vs [σсм]             axle    Pp, N3, N4, RA, RB, M
//   cross    N, Mи, S, [σи], d_min, σи(d)     (cardan_cross.h)
//   gaps     δ %, closed/intermittent/open, gap_position (idle_gap_rule.h)
//
// The seed's case (SeedCase(), the defaults of BalancerInput) reproduces every number the seed
// prints; tests/balancer/balancer_test.cpp checks each to its printed digits.
#pragma once

#include "millkit/balancer/balancer_input.h"
#include "millkit/balancer/cardan_cross.h"
#include "millkit/balancer/idle_gap_rule.h"
#include "millkit/balancer/roller_support.h"

namespace millkit::balancer {

struct BalancerResult {
  SupportReactions support;
  RollerBending roller;
  ContactCheck contact;
  AxleLoads axle;
  CrossPinCheck cross;
  IdleGapAssessment gaps;

  // True when the contact check and the adopted pin diameter pass.
  bool AllChecksPass() const { return contact.passes && cross.adopted_diameter_passes; }
};

// Validates `input` (throws InputError naming the key on the first broken rule, see
// FindInputViolation) and computes every part. The roller is loaded by P1, the larger support
// reaction, as in the seed.
BalancerResult CalculateBalancer(const BalancerInput& input);

}  // namespace millkit::balancer
