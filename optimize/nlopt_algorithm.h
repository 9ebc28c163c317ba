// Private: millkit::optimize::Algorithm → nlopt::algorithm. Only the NLopt layer's sources include
// this header, so NLopt stays out of the public headers.
#pragma once

#include <nlopt.hpp>

#include "millkit/optimize/algorithm.h"

namespace millkit::optimize {

inline nlopt::algorithm ToNlopt(Algorithm algorithm) {
  switch (algorithm) {
    case Algorithm::kLdSlsqp:
      return nlopt::LD_SLSQP;
    case Algorithm::kLdLbfgs:
      return nlopt::LD_LBFGS;
    case Algorithm::kLdMma:
      return nlopt::LD_MMA;
    case Algorithm::kLnBobyqa:
      return nlopt::LN_BOBYQA;
    case Algorithm::kLnCobyla:
      return nlopt::LN_COBYLA;
    case Algorithm::kLnNelderMead:
      return nlopt::LN_NELDERMEAD;
    case Algorithm::kLnSbplx:
      return nlopt::LN_SBPLX;
    case Algorithm::kGnDirectL:
      return nlopt::GN_DIRECT_L;
    case Algorithm::kGnIsres:
      return nlopt::GN_ISRES;
  }
  return nlopt::NUM_ALGORITHMS;  // unreachable for a valid enum value; nlopt::opt rejects it
}

}  // namespace millkit::optimize
