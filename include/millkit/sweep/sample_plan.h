// Where a what-if study samples its parameters (issue 5): a full grid, or a seeded Latin hypercube.
//
// A dimension is one named scene parameter with a range [lower, upper] on a linear or log scale,
// or (grid only) an explicit list of values. Grid values include both ends exactly:
//   linear: v_i = lower + (upper − lower) i / (n − 1);  log: v_i = lower (upper/lower)^(i/(n−1)).
// Latin hypercube of n cases: in each dimension the unit interval is cut into n equal strata and
// every stratum holds exactly one case, u = (π_d(i) + r) / n with π_d a random permutation and r
// uniform in [0, 1); the value is the linear or log image of u. The generator is std::mt19937_64
// (its output is fixed by the C++ standard) with our own bounded integers and 53-bit uniforms,
// so a seed gives the same cases on every platform.
#pragma once

#include <cstdint>
#include <vector>

#include "millkit/driveline/scene_parameter.h"

namespace millkit::sweep {

enum class Scale { kLinear, kLog };

struct SweepDimension {
  driveline::SceneParameter parameter;
  double lower = 0.0;
  double upper = 0.0;
  int points = 0;  // grid only
  Scale scale = Scale::kLinear;
  std::vector<double> values;  // grid only: explicit values (lower/upper/points unused)

  // Grid values: `values` when given, else `points` values over [lower, upper].
  std::vector<double> GridValues() const;
  // The value at unit coordinate u in [0, 1] (u = 0 → lower, u = 1 → upper exactly; the result
  // never leaves [lower, upper]).
  double FromUnit(double u) const;
  // The inverse of FromUnit for a value in [lower, upper].
  double ToUnit(double value) const;
};

// One vector of parameter values per case.
using CaseList = std::vector<std::vector<double>>;

// Every combination of the dimensions' grid values; the first dimension varies slowest (nested
// loops in the order given).
CaseList GridCases(const std::vector<SweepDimension>& dimensions);

// `count` Latin-hypercube cases over the dimensions' ranges.
CaseList LatinHypercubeCases(const std::vector<SweepDimension>& dimensions, int count,
                             std::uint64_t seed);

}  // namespace millkit::sweep
