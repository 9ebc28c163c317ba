#include "millkit/balancer/idle_gap_rule.h"

#include <cmath>
#include <stdexcept>

namespace millkit::balancer {

std::string_view ToString(IdleGapState state) {
  switch (state) {
    case IdleGapState::kClosed:
      return "closed";
    case IdleGapState::kIntermittent:
      return "intermittent";
    case IdleGapState::kOpen:
      return "open";
  }
  return "unknown";
}

IdleGapAssessment AssessIdleGaps(const BalanceSetting& setting) {
  if (!(setting.required_force_N > 0.0) || !(setting.balancing_force_N >= 0.0) ||
      !(setting.closed_within_percent >= 0.0) ||
      !(setting.open_beyond_percent >= setting.closed_within_percent)) {
    throw std::invalid_argument(
        "AssessIdleGaps: need required_force_N > 0, balancing_force_N >= 0 and "
        "0 <= closed_within_percent <= open_beyond_percent");
  }
  IdleGapAssessment r;
  r.imbalance_percent =
      100.0 * (setting.balancing_force_N - setting.required_force_N) / setting.required_force_N;
  const double deviation = std::abs(r.imbalance_percent);
  const double closed = setting.closed_within_percent;
  const double open = setting.open_beyond_percent;
  if (deviation <= closed) {
    r.state = IdleGapState::kClosed;
    r.gap_position = 1.0;
  } else if (deviation >= open) {
    r.state = IdleGapState::kOpen;
    r.gap_position = -1.0;
  } else {
    r.state = IdleGapState::kIntermittent;
    r.gap_position = 1.0 - 2.0 * (deviation - closed) / (open - closed);
  }
  r.gaps_open_at_idle = r.state != IdleGapState::kClosed;
  return r;
}

}  // namespace millkit::balancer
