// The optimisation algorithms MillKit's NLopt layer offers (optimize/coupling, optimize/leveller),
// as MillKit's own enum so that no NLopt type appears in a public header. Each maps one-to-one to
// the NLopt algorithm of the same name (optimize/nlopt_algorithm.h); AlgorithmName() spells that
// name ("LD_SLSQP"). Which algorithms a solver accepts is checked by its Options::Validate().
#pragma once

#include <string_view>

namespace millkit::optimize {

// NLopt's naming: G/L = global/local, N/D = derivative-free/gradient-based.
enum class Algorithm {
  kLdSlsqp,       // LD_SLSQP: sequential quadratic programming; takes equality constraints
  kLdLbfgs,       // LD_LBFGS: limited-memory BFGS; bounds only
  kLdMma,         // LD_MMA: method of moving asymptotes
  kLnBobyqa,      // LN_BOBYQA: quadratic models within a trust region; bounds only
  kLnCobyla,      // LN_COBYLA: linear models; takes equality constraints
  kLnNelderMead,  // LN_NELDERMEAD: simplex
  kLnSbplx,       // LN_SBPLX: subplex
  kGnDirectL,     // GN_DIRECT_L: locally biased DIRECT, global over a box
  kGnIsres,       // GN_ISRES: evolution strategy; takes equality constraints
};

constexpr std::string_view AlgorithmName(Algorithm algorithm) {
  switch (algorithm) {
    case Algorithm::kLdSlsqp:
      return "LD_SLSQP";
    case Algorithm::kLdLbfgs:
      return "LD_LBFGS";
    case Algorithm::kLdMma:
      return "LD_MMA";
    case Algorithm::kLnBobyqa:
      return "LN_BOBYQA";
    case Algorithm::kLnCobyla:
      return "LN_COBYLA";
    case Algorithm::kLnNelderMead:
      return "LN_NELDERMEAD";
    case Algorithm::kLnSbplx:
      return "LN_SBPLX";
    case Algorithm::kGnDirectL:
      return "GN_DIRECT_L";
    case Algorithm::kGnIsres:
      return "GN_ISRES";
  }
  return "unknown";
}

}  // namespace millkit::optimize
