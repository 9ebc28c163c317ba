#include "millkit/balancer/balancer.h"

namespace millkit::balancer {

BalancerResult CalculateBalancer(const BalancerInput& input) {
  Validate(input);
  BalancerResult r;
  r.support = CalcSupportReactions(input.loads.support_load_N, input.support);
  r.roller = CalcRollerBending(r.support.p1_N, input.roller);
  r.contact =
      CalcRollerContact(input.loads.support_load_N, input.loads.rod_weight_share_N, input.contact);
  r.axle = CalcRollerAxle(input.loads.support_load_N, input.support, input.axle);
  r.cross = CalcCrossPin(input.loads.rod_weight_share_N, input.cross);
  r.gaps = AssessIdleGaps(input.balance);
  return r;
}

}  // namespace millkit::balancer
