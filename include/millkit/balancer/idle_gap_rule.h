// From the balancing setting of a spindle to the state of its hinge gaps at idle and the
// gap_position a drive-line scene should start that spindle's link at (SPEC.md §2.4).
//
// What seed 000 says (Russian paper on backlash in the main line of a rolling mill):
//  - "Only a setting within ±3…5 % of exact balancing ensures that the gaps in both hinges of the
//    spindle are taken up at the same time" (fig. 2 of the seed);
//  - wrong setting of the balancing device, under- or over-balancing alike, puts radial forces in
//    the hinges that open the angular gaps at idle; the gaps then close with an impact when the
//    rolling load comes on (the case SPEC.md §2.4's default gap_position = −1 models);
//  - when the idle load moment lies between the smallest and the largest moment of the radial
//    force, a hinge with sliding liners opens and closes its gap as it turns; below the smallest,
//    the gap is open at every angle.
//
// The rule (our engineering reading of the above; the seed gives no formula):
//   δ = 100 (F − F0) / F0, percent, with F the balancing force set and F0 the force that balances
//   the spindle exactly; δ > 0 is over-balance, δ < 0 under-balance; only |δ| matters.
//   |δ| <= δc                closed:        the idle load keeps the driving flanks in contact,
//                                           gap_position = +1;
//   δc < |δ| < δo            intermittent:  the gap opens and closes as the hinge turns,
//                                           gap_position = 1 − 2 (|δ| − δc) / (δo − δc);
//   |δ| >= δo                open:          open at every angle, gap_position = −1 (the back flank:
//                                           the full clearance to travel at bite).
// δc = 3 % and δo = 5 % are the ends of the seed's "±3…5 %": we read the range as the spread of
// the limit between spindles (3 % holds for all of them, 5 % for none), which is an assumption.
// So is the linear blend in the intermittent band: it says the expected resting point moves
// evenly from the driving flank to the back flank across the band, keeping gap_position
// continuous in the balancing force (what a sweep over the force needs).
#pragma once

#include <string_view>

#include "millkit/balancer/balancer_input.h"

namespace millkit::balancer {

enum class IdleGapState { kClosed, kIntermittent, kOpen };

// "closed", "intermittent", "open".
std::string_view ToString(IdleGapState state);

struct IdleGapAssessment {
  double imbalance_percent = 0.0;  // δ, signed: > 0 over-balanced, < 0 under-balanced
  IdleGapState state = IdleGapState::kClosed;
  bool gaps_open_at_idle = false;  // true unless the state is kClosed
  double gap_position = 1.0;       // in [−1, 1], for the spindle's [[link]] (SPEC.md §2.4)
};

// The rule above. Requires F0 > 0, F >= 0, 0 <= δc <= δo; throws std::invalid_argument otherwise.
IdleGapAssessment AssessIdleGaps(const BalanceSetting& setting);

}  // namespace millkit::balancer
