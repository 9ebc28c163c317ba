#include "millkit/sweep/sample_plan.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>

#include "io/invariant.h"

namespace millkit::sweep {
namespace {

// Uniform integer in [0, n) by rejection (no modulo bias; std::uniform_int_distribution's
// algorithm is not fixed by the standard, so it would not give the same cases everywhere).
std::uint64_t BoundedInteger(std::mt19937_64& generator, std::uint64_t n) {
  const std::uint64_t limit =
      std::numeric_limits<std::uint64_t>::max() - std::numeric_limits<std::uint64_t>::max() % n;
  std::uint64_t r;
  do {
    r = generator();
  } while (r >= limit);
  return r % n;
}

// Uniform in [0, 1) with 53 random bits.
double UnitUniform(std::mt19937_64& generator) {
  return static_cast<double>(generator() >> 11) * 0x1.0p-53;
}

}  // namespace

double SweepDimension::FromUnit(double u) const {
  if (u <= 0.0) return lower;
  if (u >= 1.0) return upper;
  const double value = scale == Scale::kLog
                           ? std::exp(std::log(lower) + u * (std::log(upper) - std::log(lower)))
                           : lower + u * (upper - lower);
  return std::clamp(value, lower, upper);
}

double SweepDimension::ToUnit(double value) const {
  if (scale == Scale::kLog) {
    return (std::log(value) - std::log(lower)) / (std::log(upper) - std::log(lower));
  }
  return (value - lower) / (upper - lower);
}

std::vector<double> SweepDimension::GridValues() const {
  if (!values.empty()) return values;
  MILLKIT_CHECK(points >= 2, "a grid axis needs two points");
  std::vector<double> grid(points);
  for (int i = 0; i < points; ++i) {
    grid[i] = FromUnit(static_cast<double>(i) / static_cast<double>(points - 1));
  }
  return grid;
}

CaseList GridCases(const std::vector<SweepDimension>& dimensions) {
  std::vector<std::vector<double>> axes;
  size_t total = 1;
  for (const auto& d : dimensions) {
    axes.push_back(d.GridValues());
    total *= axes.back().size();
  }
  CaseList cases(dimensions.empty() ? 0 : total, std::vector<double>(dimensions.size()));
  for (size_t c = 0; c < cases.size(); ++c) {
    size_t rest = c;
    for (size_t d = dimensions.size(); d-- > 0;) {  // the last dimension varies fastest
      cases[c][d] = axes[d][rest % axes[d].size()];
      rest /= axes[d].size();
    }
  }
  return cases;
}

CaseList LatinHypercubeCases(const std::vector<SweepDimension>& dimensions, int count,
                             std::uint64_t seed) {
  MILLKIT_CHECK(count >= 1, "a sample plan needs a case");
  std::mt19937_64 generator(seed);
  CaseList cases(count, std::vector<double>(dimensions.size()));
  std::vector<int> stratum(count);
  for (size_t d = 0; d < dimensions.size(); ++d) {
    std::iota(stratum.begin(), stratum.end(), 0);
    for (int i = count - 1; i > 0; --i) {  // Fisher–Yates
      std::swap(stratum[i], stratum[BoundedInteger(generator, static_cast<std::uint64_t>(i) + 1)]);
    }
    for (int i = 0; i < count; ++i) {
      const double u = (stratum[i] + UnitUniform(generator)) / count;
      cases[i][d] = dimensions[d].FromUnit(u);
    }
  }
  return cases;
}

}  // namespace millkit::sweep
